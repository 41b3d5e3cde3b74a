//! Scenes a depth scale cannot have made: the median depth hundreds of metres away, or the
//! ground several metres below a camera whose depth says it looks at a room. Each is named
//! with the depth scale that would make the scene plausible (TUM's 5000 units/m read as
//! millimetres puts a desk 7.5 m away and the floor 7.5 m below).

use std::fmt;

use tre_core::geometry::Grid;

use super::gravity::Gravity;

/// Median depth from which a frame's scale is implausible, metres (no depth sensor's median
/// is this far).
pub const MAX_MEDIAN_DEPTH_M: f64 = 150.0;
/// Height of an estimated ground plane under the camera from which the scale is suspect,
/// metres (above a truck's roof).
pub const MAX_GROUND_BELOW_M: f64 = 4.0;
/// Depth scales (units per metre) that depth files use: metres, millimetres, TUM's fifths of
/// a millimetre, tenths of a millimetre.
const COMMON_SCALES: [f64; 4] = [1.0, 1000.0, 5000.0, 10_000.0];
/// What a plausible scene has: a hand-held or robot camera ~1.2 m above the ground, a median
/// depth of a few metres.
const TYPICAL_HEIGHT_M: f64 = 1.2;
const TYPICAL_MEDIAN_M: f64 = 3.0;

/// Why a frame's depth looks wrongly scaled.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Implausible {
    /// The median depth is over [`MAX_MEDIAN_DEPTH_M`].
    FarDepth {
        /// Median of the valid depth, metres.
        median_m: f64,
    },
    /// The depth's own ground plane is over [`MAX_GROUND_BELOW_M`] below the camera.
    DeepGround {
        /// The fitted ground's distance below the camera, metres.
        height_m: f64,
        /// Median of the valid depth, metres.
        median_m: f64,
    },
}

impl Implausible {
    /// The check of one frame's depth (metres) and the gravity found for it; stated mounting
    /// is never questioned. One counting pass per frame; the median is sorted out only for a
    /// frame that fails.
    pub fn of(depth_m: &Grid<f64>, gravity: &Gravity) -> Option<Self> {
        let (mut valid, mut far) = (0usize, 0usize);
        for &d in depth_m.as_slice() {
            if d.is_finite() && d > 0.0 {
                valid += 1;
                far += usize::from(d > MAX_MEDIAN_DEPTH_M);
            }
        }
        // The median (the valid depth at `valid / 2` in order) is over the limit exactly when
        // the `valid - valid / 2` largest are.
        if valid == 0 {
            return None;
        }
        if far >= valid - valid / 2 {
            return Some(Self::FarDepth {
                median_m: median(depth_m),
            });
        }
        match gravity {
            Gravity::Estimated(fit) if fit.height_m > MAX_GROUND_BELOW_M => {
                Some(Self::DeepGround {
                    height_m: fit.height_m,
                    median_m: median(depth_m),
                })
            }
            _ => None,
        }
    }

    /// The common depth scale that would make the scene typical, given the scale the depth was
    /// read with (units per metre); `None` when that is the one given.
    pub fn likely_scale(&self, stated: f64) -> Option<f64> {
        let (value, typical) = match *self {
            Self::FarDepth { median_m } => (median_m, TYPICAL_MEDIAN_M),
            Self::DeepGround { height_m, .. } => (height_m, TYPICAL_HEIGHT_M),
        };
        let raw = value * stated;
        let best = COMMON_SCALES.into_iter().min_by(|a, b| {
            let off = |s: f64| ((raw / s) / typical).ln().abs();
            off(*a).total_cmp(&off(*b))
        })?;
        (best != stated).then_some(best)
    }

    /// The warning, naming the likely scale for depth read with `stated` units per metre.
    pub fn message(&self, stated: f64) -> String {
        let what = match *self {
            Self::FarDepth { median_m } => format!("the median depth is {median_m:.0} m"),
            Self::DeepGround { height_m, median_m } => format!(
                "the ground fits {height_m:.1} m below the camera (median depth {median_m:.1} m)"
            ),
        };
        match self.likely_scale(stated) {
            Some(s) => format!(
                "{what}: the depth scale is likely wrong: read with {stated} units per metre, \
                 {s} would make it a typical scene (set depth_scale in the camera file)"
            ),
            None => format!("{what}: check the depth scale ({stated} units per metre)"),
        }
    }
}

/// The median of the valid depth (the element at `n / 2` in order), metres.
fn median(depth_m: &Grid<f64>) -> f64 {
    let mut valid: Vec<f64> = depth_m
        .as_slice()
        .iter()
        .copied()
        .filter(|d| d.is_finite() && *d > 0.0)
        .collect();
    let mid = valid.len() / 2;
    *valid.select_nth_unstable_by(mid, f64::total_cmp).1
}

impl fmt::Display for Implausible {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(&self.message(1000.0))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::gravity::GravityUnknown;
    use tre_core::geometry::floor::FloorFit;
    use tre_core::geometry::Vec3;

    fn fit(height_m: f64) -> Gravity {
        Gravity::Estimated(FloorFit {
            up_in_cam: Vec3::new(0.0, -1.0, 0.0),
            height_m,
            pitch_rad: 0.0,
            roll_rad: 0.0,
            support: 0.5,
            below: 0.0,
            points: 1000,
            confident: true,
        })
    }

    #[test]
    fn tum_depth_read_as_millimetres_names_5000() {
        // A TUM desk frame read with 1000: depth and height five times too large.
        let depth = Grid::new(8, 8, 7.5);
        let bad = Implausible::of(&depth, &fit(7.6)).unwrap();
        assert_eq!(bad.likely_scale(1000.0), Some(5000.0));
        assert!(
            bad.message(1000.0).contains("5000"),
            "{}",
            bad.message(1000.0)
        );
        // The same frame read right is fine; so is a stated mounting or no gravity.
        assert_eq!(Implausible::of(&Grid::new(8, 8, 1.5), &fit(1.5)), None);
        let unknown = Gravity::Unknown(GravityUnknown::NoDepth);
        assert_eq!(Implausible::of(&depth, &unknown), None);
    }

    #[test]
    fn metres_read_as_millimetres_are_far() {
        // Depth in millimetres read as metres: a 3 m scene at 3000 m.
        let bad = Implausible::of(&Grid::new(8, 8, 3000.0), &fit(1.0)).unwrap();
        assert!(matches!(bad, Implausible::FarDepth { .. }));
        assert_eq!(bad.likely_scale(1.0), Some(1000.0));
    }
}
