//! Depth-sensor noise σ_z(z) (presets and explicit coefficients) and the uncertainty map: the
//! roughness that noise alone gives annotation spec v1 on a flat surface (docs/sensor-noise.md).

use std::fmt;
use std::str::FromStr;

use serde::{Deserialize, Serialize};

mod uncertainty;

pub use uncertainty::{
    erfc, pixel_noise_map, uncertainty_map, PixelNoise, HALF_NORMAL_P95, MAX_OF_8_HALF_NORMAL_P95,
    SEGMENT_BREAK_FRACTION,
};

/// A named depth sensor whose noise model is built in (sources in docs/sensor-noise.md).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum SensorPreset {
    /// Structured light, Kinect v1: σ_z = 1.2 mm + 1.9 mm·(z − 0.4 m)² (Nguyen et al. 2012).
    KinectV1,
    /// Active stereo, RealSense D435 at 848×480: σ_z = z²·σ_d/(f·b), σ_d = 0.08 px,
    /// f = 447 px, b = 50 mm (Intel's D400 tuning white paper).
    RealsenseD435,
    /// Time of flight, Azure Kinect DK: constant 17 mm (the hardware spec's random-error bound).
    AzureKinect,
    /// Spinning LiDAR (HDL-64E class, ±2 cm), one sweep: constant 20 mm.
    Lidar,
    /// Accumulated (semi-dense) LiDAR: several sweeps moved into one frame by the poses. The
    /// range noise of one sweep (20 mm) plus the sweeps' registration error, an angle of
    /// [`REGISTRATION_DEG`] that offsets whole scan lines (correlated, so averaging does not
    /// remove it): [`SensorNoise::registration_m`].
    LidarAccumulated,
    /// Passive stereo (a ZED-class rig: baseline 120 mm, focal length 700 px at 1280×720, the
    /// matcher's sub-pixel step 0.25 px): σ_z = z²·step/(f·b). Another rig: explicit
    /// coefficients `[0, 0, 1000·step/(f·b)]` mm (docs/sensor-noise.md).
    PassiveStereo,
    /// Exact depth (synthetic data): no noise.
    Exact,
}

impl SensorPreset {
    /// Every preset, in the order the docs list them.
    pub const ALL: [Self; 7] = [
        Self::KinectV1,
        Self::RealsenseD435,
        Self::AzureKinect,
        Self::Lidar,
        Self::LidarAccumulated,
        Self::PassiveStereo,
        Self::Exact,
    ];

    /// The preset's name on the wire (`kinect_v1`, …), as serde writes it.
    pub fn name(self) -> &'static str {
        match self {
            Self::KinectV1 => "kinect_v1",
            Self::RealsenseD435 => "realsense_d435",
            Self::AzureKinect => "azure_kinect",
            Self::Lidar => "lidar",
            Self::LidarAccumulated => "lidar_accumulated",
            Self::PassiveStereo => "passive_stereo",
            Self::Exact => "exact",
        }
    }

    /// The names of all presets, comma-separated (for messages).
    pub fn names() -> String {
        Self::ALL.map(Self::name).join(", ")
    }

    /// σ_z(z), metres, for depth `z_m` metres.
    pub fn sigma_z_m(self, z_m: f64) -> f64 {
        match self {
            Self::KinectV1 => 0.0012 + 0.0019 * (z_m - 0.4).powi(2),
            Self::RealsenseD435 => z_m * z_m * D435_SUBPIXEL_PX / (D435_FOCAL_PX * D435_BASELINE_M),
            Self::AzureKinect => 0.017,
            Self::Lidar | Self::LidarAccumulated => 0.02,
            Self::PassiveStereo => {
                z_m * z_m * STEREO_SUBPIXEL_PX / (STEREO_FOCAL_PX * STEREO_BASELINE_M)
            }
            Self::Exact => 0.0,
        }
    }
}

/// [`SensorNoise::mean_variance`] for a correlation window `(side, share)` already in the
/// frame's pixels ([`SensorNoise::correlation_in`]).
pub fn shared_mean_variance((c, s): (f64, f64), n: f64) -> f64 {
    let n = n.max(1.0);
    (1.0 - s) / n + s * (c * c / n).min(1.0)
}

/// Registration error of accumulated LiDAR sweeps, degrees: at 10 m it offsets a sweep's scan
/// lines by 5 cm. The one semi-dense set here (real-rgbd-3) shows layers of about this size.
pub const REGISTRATION_DEG: f64 = 0.3;
/// Passive stereo preset: the matcher's sub-pixel step, pixels.
const STEREO_SUBPIXEL_PX: f64 = 0.25;
/// Passive stereo preset: focal length, pixels (ZED class at 1280×720).
const STEREO_FOCAL_PX: f64 = 700.0;
/// Passive stereo preset: baseline, metres.
const STEREO_BASELINE_M: f64 = 0.12;

/// Kinect v1 depth focal length at 640×480, pixels (the synthetic sensor model's).
const KINECT_V1_FOCAL_PX: f64 = 580.0;
/// RealSense D435 sub-pixel disparity accuracy σ_d, pixels (Intel's typical figure).
const D435_SUBPIXEL_PX: f64 = 0.08;
/// RealSense D435 depth focal length at 848×480 (87° horizontal field of view), pixels.
const D435_FOCAL_PX: f64 = 447.0;
/// RealSense D435 stereo baseline, metres.
const D435_BASELINE_M: f64 = 0.050;

impl fmt::Display for SensorPreset {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

impl FromStr for SensorPreset {
    type Err = UnknownSensor;

    /// A preset by name (case and `-`/`_` do not matter).
    ///
    /// ```
    /// use tre_core::roughness::noise::SensorPreset;
    /// assert_eq!("Kinect-V1".parse(), Ok(SensorPreset::KinectV1));
    /// let e = "kinect".parse::<SensorPreset>().unwrap_err();
    /// assert!(e.to_string().contains("kinect_v1"), "{e}");
    /// ```
    fn from_str(s: &str) -> Result<Self, UnknownSensor> {
        let key = s.trim().to_ascii_lowercase().replace('-', "_");
        Self::ALL
            .into_iter()
            .find(|p| p.name() == key)
            .ok_or_else(|| UnknownSensor { name: s.to_owned() })
    }
}

/// A name that is no preset's ([`SensorPreset`]'s `FromStr`); the message lists the presets.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("unknown sensor {name:?}: the presets are {}", SensorPreset::names())]
pub struct UnknownSensor {
    /// The name given.
    pub name: String,
}

/// A depth-noise model: a preset, or σ_z(z) = a + b·z + c·z² millimetres with z in metres.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(untagged)]
pub enum SensorNoise {
    /// A built-in sensor.
    Preset(SensorPreset),
    /// Explicit coefficients.
    Coefficients {
        /// `[a, b, c]`: σ_z = a + b·z + c·z² mm, z in metres.
        sigma_mm: [f64; 3],
    },
    /// A passive stereo rig: `{"stereo": {"baseline_m", "focal_px", "step_px", "block_px"}}`.
    Stereo {
        /// The rig.
        stereo: StereoRig,
    },
}

/// A passive stereo rig's noise: σ_z = z²·step/(f·b) (the matcher's sub-pixel step as the
/// disparity's σ), errors shared over the matcher's block.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct StereoRig {
    /// Baseline b, metres.
    pub baseline_m: f64,
    /// Focal length f of the rectified pair, pixels.
    pub focal_px: f64,
    /// The matcher's sub-pixel disparity step, pixels (0.25 for a quarter-pixel matcher).
    pub step_px: f64,
    /// Side of the matcher's block, pixels (errors are shared within it).
    #[serde(default = "default_block_px")]
    pub block_px: f64,
}

fn default_block_px() -> f64 {
    5.0
}

impl StereoRig {
    /// The rig checked: every field a positive, finite number, else what is wrong.
    ///
    /// # Errors
    ///
    /// [`StereoRigError`], naming the first field that is not.
    pub fn checked(self) -> Result<Self, StereoRigError> {
        for (field, value) in [
            ("baseline_m", self.baseline_m),
            ("focal_px", self.focal_px),
            ("step_px", self.step_px),
            ("block_px", self.block_px),
        ] {
            if !(value.is_finite() && value > 0.0) {
                return Err(StereoRigError { field, value });
            }
        }
        Ok(self)
    }

    /// σ_z(z), metres.
    pub fn sigma_z_m(&self, z_m: f64) -> f64 {
        z_m * z_m * self.sigma_mm()[2] * 1e-3
    }

    /// The rig's σ_z as coefficients `[a, b, c]` mm (σ_z = c·z²), as the stream and the query
    /// carry it (without the block's correlation).
    pub fn sigma_mm(&self) -> [f64; 3] {
        [
            0.0,
            0.0,
            1e3 * self.step_px / (self.focal_px * self.baseline_m),
        ]
    }
}

/// A stereo rig field that is not a positive, finite number ([`StereoRig::checked`]); the
/// message names it, `sensor.stereo.<field>`.
#[derive(Debug, Clone, Copy, PartialEq, thiserror::Error)]
#[error("sensor.stereo.{field} must be a positive number, got {value}")]
pub struct StereoRigError {
    /// The field's name (`baseline_m`, `focal_px`, `step_px` or `block_px`).
    pub field: &'static str,
    /// The value given.
    pub value: f64,
}

impl SensorNoise {
    /// Explicit coefficients `[a, b, c]` (σ_z = a + b·z + c·z² mm), checked: finite, with
    /// σ_z ≥ 0 for every z ≥ 0 (so `c ≥ 0`, and `b ≥ 0` when `c = 0`). For why not, an error
    /// whose message names the field.
    ///
    /// ```
    /// use tre_core::roughness::noise::{CoefficientsProblem, SensorNoise};
    /// let kinect = SensorNoise::coefficients([1.504, -1.52, 1.9]).unwrap();
    /// assert!((kinect.sigma_z_m(4.0) - 0.025_824).abs() < 1e-9);
    /// let e = SensorNoise::coefficients([1.0, 0.0, -1.0]).unwrap_err();
    /// assert_eq!(e.problem, CoefficientsProblem::Negative);
    /// assert!(e.to_string().contains("sigma_mm"));
    /// ```
    pub fn coefficients(sigma_mm: [f64; 3]) -> Result<Self, CoefficientsError> {
        let [a, b, c] = sigma_mm;
        let bad = |problem| Err(CoefficientsError { sigma_mm, problem });
        if !sigma_mm.iter().all(|v| v.is_finite()) {
            return bad(CoefficientsProblem::NotFinite);
        }
        if a < 0.0 || c < 0.0 || (c == 0.0 && b < 0.0) {
            return bad(CoefficientsProblem::Negative);
        }
        if c > 0.0 && b < 0.0 && a - b * b / (4.0 * c) < 0.0 {
            return bad(CoefficientsProblem::DipsBelowZero);
        }
        Ok(Self::Coefficients { sigma_mm })
    }

    /// σ_z(z), metres, for depth `z_m` metres.
    pub fn sigma_z_m(&self, z_m: f64) -> f64 {
        match self {
            Self::Preset(p) => p.sigma_z_m(z_m),
            Self::Coefficients {
                sigma_mm: [a, b, c],
            } => (a + b * z_m + c * z_m * z_m) * 1e-3,
            Self::Stereo { stereo } => stereo.sigma_z_m(z_m),
        }
    }

    /// How the noise is shared between neighbouring pixels: `(side, share)`, the side in the
    /// sensor's own (native) pixels of the patches within which a `share` of the variance is
    /// common (a triangulating sensor's correlation window, as the synthetic sensor models
    /// render it: docs/synth.md), `(1, 0)` for independent pixels.
    pub fn correlation(&self) -> (f64, f64) {
        match self {
            Self::Preset(SensorPreset::KinectV1) => (9.0, 0.9),
            Self::Preset(SensorPreset::RealsenseD435) => (7.0, 0.8),
            Self::Preset(SensorPreset::PassiveStereo) => (5.0, 0.5),
            Self::Stereo { stereo } => (stereo.block_px, 0.5),
            _ => (1.0, 0.0),
        }
    }

    /// The focal length of the sensor's own depth image, pixels, which its
    /// [`correlation`](Self::correlation) window is given in (`None`: independent pixels).
    pub fn native_focal_px(&self) -> Option<f64> {
        match self {
            Self::Preset(SensorPreset::KinectV1) => Some(KINECT_V1_FOCAL_PX),
            Self::Preset(SensorPreset::RealsenseD435) => Some(D435_FOCAL_PX),
            Self::Preset(SensorPreset::PassiveStereo) => Some(STEREO_FOCAL_PX),
            Self::Stereo { stereo } => Some(stereo.focal_px),
            _ => None,
        }
    }

    /// [`correlation`](Self::correlation) in the pixels of a frame of focal lengths
    /// `(fx, fy)`: the window covers the same angles whatever size the frame was resampled
    /// to (a 640×480 Kinect frame halved to 320×240 shares its noise over 4.5 px, not 9). A
    /// frame resampled by different factors along its axes gets the side of a square of the
    /// window's area.
    pub fn correlation_in(&self, (fx_px, fy_px): (f64, f64)) -> (f64, f64) {
        let (side, share) = self.correlation();
        let scale = (fx_px * fy_px).sqrt();
        match self.native_focal_px() {
            Some(f) if scale.is_finite() && scale > 0.0 => ((side * scale / f).max(1.0), share),
            _ => (side, share),
        }
    }

    /// The variance of the mean of `n` neighbouring points' noise, in units of one point's,
    /// in a frame of focal lengths `(fx, fy)`: `(1 − s)/n + s·min(1, c²/n)` for side `c` and
    /// share `s` ([`Self::correlation_in`]).
    pub fn mean_variance(&self, n: f64, focal_px: (f64, f64)) -> f64 {
        shared_mean_variance(self.correlation_in(focal_px), n)
    }

    /// The correlated part of the noise at range `z_m`, metres: an offset shared by many
    /// neighbouring points (a sweep's scan lines, for accumulated LiDAR), which averaging over
    /// a window does not reduce. 0 for every sensor but accumulated LiDAR.
    pub fn registration_m(&self, z_m: f64) -> f64 {
        match self {
            Self::Preset(SensorPreset::LidarAccumulated) => {
                z_m * REGISTRATION_DEG.to_radians().tan()
            }
            _ => 0.0,
        }
    }

    /// True for a scanning LiDAR (one sweep or accumulated): its pixels without depth are
    /// mostly the gaps between scan lines on surfaces it does see, which cleaned depth may
    /// fill from a support's plane. A camera's (and an unnamed sensor's) are shadows and
    /// dropouts beside edges, where such a plane reads a drop as flat: they stay empty.
    pub fn fills_scan_gaps(&self) -> bool {
        matches!(
            self,
            Self::Preset(SensorPreset::Lidar | SensorPreset::LidarAccumulated)
        )
    }

    /// The preset's name, or `sigma_mm [a, b, c]`.
    pub fn label(&self) -> String {
        match self {
            Self::Preset(p) => p.name().to_string(),
            Self::Coefficients { sigma_mm } => format!("sigma_mm {sigma_mm:?}"),
            Self::Stereo { stereo } => format!(
                "stereo b {} m, f {} px, step {} px",
                stereo.baseline_m, stereo.focal_px, stereo.step_px
            ),
        }
    }
}

/// Coefficients `[a, b, c]` that make no noise model ([`SensorNoise::coefficients`]); the
/// message names the field, `sensor.sigma_mm`.
#[derive(Debug, Clone, Copy, PartialEq, thiserror::Error)]
#[error("sensor.sigma_mm {sigma_mm:?}: {problem}")]
pub struct CoefficientsError {
    /// The coefficients given.
    pub sigma_mm: [f64; 3],
    /// What is wrong with them.
    pub problem: CoefficientsProblem,
}

/// What is wrong with noise coefficients `[a, b, c]`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, thiserror::Error)]
pub enum CoefficientsProblem {
    /// A coefficient that is NaN or infinite.
    #[error("all three coefficients must be finite numbers")]
    NotFinite,
    /// `a < 0` or `c < 0` (or `b < 0` with `c = 0`): σ_z falls below 0 as z grows.
    #[error("σ_z = a + b·z + c·z² mm must stay ≥ 0 for z ≥ 0 (a ≥ 0, c ≥ 0)")]
    Negative,
    /// A parabola whose minimum, at some z > 0, is below 0.
    #[error("σ_z = a + b·z + c·z² mm dips below 0 at some z > 0")]
    DipsBelowZero,
}

/// Text that names no noise model ([`SensorNoise`]'s `FromStr`: a preset name or `a,b,c`).
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum SensorParseError {
    /// A name that is no preset's.
    #[error(transparent)]
    Unknown(#[from] UnknownSensor),
    /// Text with commas that is not three numbers.
    #[error("sensor {text:?}: coefficients are three numbers a,b,c (mm)")]
    NotThreeNumbers {
        /// The text given.
        text: String,
    },
    /// Three numbers that make no noise model.
    #[error(transparent)]
    Coefficients(#[from] CoefficientsError),
}

impl FromStr for SensorNoise {
    type Err = SensorParseError;

    /// A preset name, or `a,b,c` coefficients in millimetres.
    fn from_str(s: &str) -> Result<Self, SensorParseError> {
        if s.contains(',') {
            let v: Result<Vec<f64>, _> = s.split(',').map(|c| c.trim().parse::<f64>()).collect();
            return match v.as_deref() {
                Ok(&[a, b, c]) => Ok(Self::coefficients([a, b, c])?),
                _ => Err(SensorParseError::NotThreeNumbers { text: s.to_owned() }),
            };
        }
        Ok(s.parse().map(Self::Preset)?)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn preset_names_are_serdes_and_parse_back() {
        for p in SensorPreset::ALL {
            let json = serde_json::to_string(&SensorNoise::Preset(p)).unwrap();
            assert_eq!(json, format!("\"{}\"", p.name()));
            assert_eq!(p.name().parse::<SensorPreset>(), Ok(p));
            assert_eq!(
                serde_json::from_str::<SensorNoise>(&json).unwrap(),
                SensorNoise::Preset(p)
            );
        }
    }

    #[test]
    fn presets_give_the_cited_figures() {
        let k = SensorPreset::KinectV1;
        assert!((k.sigma_z_m(0.4) - 0.0012).abs() < 1e-12);
        assert!((k.sigma_z_m(4.0) - (0.0012 + 0.0019 * 12.96)).abs() < 1e-12);
        // D435: 1 m → 0.08 / (447 · 0.05) = 3.58 mm; quadratic in z.
        let d = SensorPreset::RealsenseD435;
        assert!((d.sigma_z_m(1.0) - 0.003_579).abs() < 1e-6);
        assert!((d.sigma_z_m(2.0) / d.sigma_z_m(1.0) - 4.0).abs() < 1e-9);
        assert_eq!(SensorPreset::Exact.sigma_z_m(10.0), 0.0);
        assert_eq!(SensorPreset::Lidar.sigma_z_m(30.0), 0.02);
    }

    #[test]
    fn coefficients_parse_from_text_and_json() {
        let c: SensorNoise = "1.5, 0, 2".parse().unwrap();
        assert!((c.sigma_z_m(2.0) - 0.0095).abs() < 1e-12);
        let j: SensorNoise = serde_json::from_str(r#"{"sigma_mm": [1.5, 0, 2]}"#).unwrap();
        assert_eq!(j, c);
        assert!("1,2".parse::<SensorNoise>().is_err());
        assert!(SensorNoise::coefficients([1.0, -4.0, 1.0]).is_err());
        assert!(SensorNoise::coefficients([f64::NAN, 0.0, 1.0]).is_err());
    }
}
