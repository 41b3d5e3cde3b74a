//! Where a frame's gravity came from, and what stood in for what the user did not give: every
//! answer reports both (`tre infer` as warnings, HTTP as headers, the stream as fields).
//!
//! Slope and the traversability maps need gravity's up axis. A stated mounting gives it; a
//! depth frame without one gets it from its own ground plane
//! ([`fit_floor`](tre_core::geometry::floor::fit_floor)); when that fit is not confident, or
//! there is no depth (`rgb`), gravity is *unknown*: slopes are NaN, no pixel is traversable,
//! and the three-state map says unknown wherever its roughness does not already make a hazard.

use std::fmt;

use tre_core::geometry::floor::{FloorFit, NoFloor};
use tre_core::geometry::{Mounting, Vec3};

use super::Mode;

/// Gravity for one frame.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Gravity {
    /// From the mounting the frame states.
    Stated(Mounting),
    /// From the frame's depth: a confident ground fit.
    Estimated(FloorFit),
    /// Neither: slope and traversability are unknown.
    Unknown(GravityUnknown),
}

/// Why a frame's gravity is unknown.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum GravityUnknown {
    /// No mounting stated and no sensor depth to find the ground in (`rgb`).
    NoDepth,
    /// The depth shows no plane that could be the ground.
    NoFloor(NoFloor),
    /// A ground plane, but too little of the frame on it, or too much below it.
    NotConfident(FloorFit),
}

impl Gravity {
    /// Gravity's up axis in the camera frame, if known.
    pub fn up_in_cam(&self) -> Option<Vec3> {
        match self {
            Self::Stated(m) => Some(m.up_in_cam()),
            Self::Estimated(f) => Some(f.up_in_cam),
            Self::Unknown(_) => None,
        }
    }

    /// `stated`, `estimated` or `unknown`.
    pub fn source(&self) -> &'static str {
        match self {
            Self::Stated(_) => "stated",
            Self::Estimated(_) => "estimated",
            Self::Unknown(_) => "unknown",
        }
    }

    /// Pitch and roll below the horizon (degrees), the camera's height (metres) and the fit's
    /// support (fraction of the points on the ground), as far as known.
    pub fn figures(&self) -> Option<GravityFigures> {
        match self {
            Self::Stated(m) => Some(GravityFigures {
                pitch_deg: m.pitch_rad.to_degrees(),
                roll_deg: 0.0,
                height_m: m.height_m,
                support: None,
            }),
            Self::Estimated(f) | Self::Unknown(GravityUnknown::NotConfident(f)) => {
                Some(GravityFigures {
                    pitch_deg: f.pitch_rad.to_degrees(),
                    roll_deg: f.roll_rad.to_degrees(),
                    height_m: f.height_m,
                    support: Some(f.support),
                })
            }
            Self::Unknown(_) => None,
        }
    }
}

/// Gravity's figures as reported.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct GravityFigures {
    /// Pitch of the optical axis below the horizon, degrees.
    pub pitch_deg: f64,
    /// Roll about the optical axis, degrees.
    pub roll_deg: f64,
    /// Camera height above the ground, metres.
    pub height_m: f64,
    /// Fraction of the sampled points on the fitted ground (estimates only).
    pub support: Option<f64>,
}

impl fmt::Display for Gravity {
    /// One line, also the `x-tre-gravity` header: `stated; pitch_deg=60.0; roll_deg=0.0;
    /// height_m=1.00`, `estimated; …; support=0.18`, or `unknown; reason="…"`.
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}", self.source())?;
        if let (Self::Stated(_) | Self::Estimated(_), Some(g)) = (self, self.figures()) {
            write!(
                f,
                "; pitch_deg={:.1}; roll_deg={:.1}; height_m={:.2}",
                g.pitch_deg, g.roll_deg, g.height_m
            )?;
            if let Some(s) = g.support {
                write!(f, "; support={s:.3}")?;
            }
        }
        if let Self::Unknown(why) = self {
            write!(f, "; reason=\"{why}\"")?;
        }
        Ok(())
    }
}

impl fmt::Display for GravityUnknown {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::NoDepth => write!(
                f,
                "no mounting stated (pitch_deg, height_m) and no sensor depth to find the ground in"
            ),
            Self::NoFloor(e) => write!(f, "no mounting stated and {e}"),
            Self::NotConfident(fit) => write!(
                f,
                "no mounting stated and the ground fit is not confident ({:.1}% of the points on \
                 it, {:.1}% below it; needs at least 5% on and at most 1% below)",
                100.0 * fit.support,
                100.0 * fit.below
            ),
        }
    }
}

/// Something the user did not give, and what stood in for it.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Assumption {
    /// No intrinsics: a pinhole with a 60° horizontal field of view, centred.
    Intrinsics,
    /// A 16-bit depth PNG without a stated `depth_scale`, read as millimetres.
    DepthScale,
    /// No mounting: the `rgb` depth prior from a camera 60° down and 1 m up.
    Mounting,
    /// No depth-sensor model in the `geometric` mode: the depth read as exact (no noise
    /// margin; the spec on cleaned depth cleans nothing).
    Sensor,
    /// No mode asked for: chosen from the inputs.
    Mode(Mode),
}

impl Assumption {
    /// The short name, as in the `x-tre-assumed` header and the stream's `assumed` field.
    pub fn key(&self) -> &'static str {
        match self {
            Self::Intrinsics => "intrinsics",
            Self::DepthScale => "depth_scale",
            Self::Mounting => "mounting",
            Self::Sensor => "sensor",
            Self::Mode(_) => "mode",
        }
    }

    /// The assumptions of a frame: `intrinsics` and `depth_png` as given (`depth_scale`: the
    /// camera's, if stated), `mounting_stated`, `sensor_named` (a noise model, from the request
    /// or the camera), the mode that ran and whether it was asked for.
    pub fn of_frame(
        has_intrinsics: bool,
        depth_png_without_scale: bool,
        (mounting_stated, sensor_named): (bool, bool),
        (mode, asked): (Mode, bool),
    ) -> Vec<Self> {
        let mut out = Vec::new();
        if !has_intrinsics {
            out.push(Self::Intrinsics);
        }
        if depth_png_without_scale && mode != Mode::Rgb {
            out.push(Self::DepthScale);
        }
        if !mounting_stated && mode == Mode::Rgb {
            out.push(Self::Mounting);
        }
        if !sensor_named && mode == Mode::Geometric {
            out.push(Self::Sensor);
        }
        if !asked {
            out.push(Self::Mode(mode));
        }
        out
    }
}

impl fmt::Display for Assumption {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::Intrinsics => write!(
                f,
                "no camera intrinsics: assumed a pinhole with a 60° horizontal field of view, \
                 centred (give fx, fy, cx, cy)"
            ),
            Self::DepthScale => write!(
                f,
                "no depth_scale: the 16-bit depth was read as millimetres (1000 units per metre; \
                 TUM files use 5000)"
            ),
            Self::Mounting => write!(
                f,
                "no mounting: the rgb depth prior assumed a camera 60° down and 1 m up \
                 (give pitch_deg, height_m); slope and traversability are unknown"
            ),
            Self::Sensor => write!(
                f,
                "no depth-sensor model: the depth was read as exact, with no noise margin \
                 (name the sensor: \"sensor\" in the camera JSON, or --sensor)"
            ),
            Self::Mode(m) => write!(
                f,
                "no mode asked for: ran {m}, chosen from the inputs (ask for rgb, rgbd or geometric)"
            ),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn assumptions_name_what_stood_in() {
        let a = Assumption::of_frame(false, true, (false, false), (Mode::Rgbd, false));
        let keys: Vec<_> = a.iter().map(Assumption::key).collect();
        assert_eq!(keys, ["intrinsics", "depth_scale", "mode"]);
        let a = Assumption::of_frame(true, false, (false, false), (Mode::Rgb, true));
        assert_eq!(a, [Assumption::Mounting]);
        assert!(
            Assumption::of_frame(true, false, (true, true), (Mode::Geometric, true)).is_empty()
        );
        // The geometric mode without a noise model reads the depth as exact, and says so.
        let a = Assumption::of_frame(true, false, (true, false), (Mode::Geometric, true));
        assert_eq!(a, [Assumption::Sensor]);
        assert!(a[0].to_string().contains("exact"));
    }

    #[test]
    fn gravity_lines_name_their_source() {
        let m = Gravity::Stated(Mounting::default());
        assert_eq!(
            m.to_string(),
            "stated; pitch_deg=60.0; roll_deg=0.0; height_m=1.00"
        );
        let u = Gravity::Unknown(GravityUnknown::NoDepth);
        assert!(u.to_string().starts_with("unknown; reason=\"no mounting"));
        assert!(u.up_in_cam().is_none());
    }
}
