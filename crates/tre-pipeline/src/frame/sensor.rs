//! A frame's sensor-noise maps ([`SensorMaps`]): the uncertainty map, the calibrated interval
//! and three-state traversability, read from a [`FrameOutput`] at the frame's size.

use super::{FrameInput, FrameOutput, DEFAULT_HFOV_DEG};
use crate::{Mode, PipelineError, Traversability};
use tre_core::geometry::{Grid, Intrinsics, Vec3};
use tre_core::roughness::annotate::AnnotateConfig;
use tre_core::roughness::interval::{self, IntervalTable, SecondAxis};
use tre_core::roughness::noise::{uncertainty_map, SensorNoise};
use tre_core::roughness::traversal::{ThreeStateRule, Traversal};

/// The sensor-noise maps of a frame, at the frame's size (docs/sensor-noise.md,
/// docs/uncertainty.md).
#[derive(Debug, Clone)]
pub struct SensorMaps {
    /// Depth modes: the p95 of the roughness sensor noise alone gives spec v1 on a flat
    /// surface; `rgb` (calibrated interval only): the interval's half-width. Metres (NaN: no
    /// roughness).
    pub uncertainty_m: Grid<f64>,
    /// The calibrated 90% interval `(lo, hi)` of the spec's value, metres, when the mode has
    /// a calibration table.
    pub interval_m: Option<(Grid<f64>, Grid<f64>)>,
    /// Three-state traversability.
    pub traversal: Grid<Traversal>,
}

impl FrameOutput {
    /// The uncertainty and three-state maps of a frame. With a calibration `table` for the
    /// mode (docs/uncertainty.md) the map reads the calibrated interval (`rgb`: no sensor depth
    /// or noise model needed); without one, the depth modes read the sensor model alone
    /// (docs/sensor-noise.md). `sensor`: the camera's noise model (`None`: it gave none;
    /// `described`: its free-text sensor, if any); the frame's intrinsics (or the 60° default)
    /// and this output's normals. For `rgb` without a table, and the end-to-end baseline, an
    /// error.
    ///
    /// # Errors
    ///
    /// [`PipelineError::NoSensorDepth`] for a mode without sensor depth and no table,
    /// [`PipelineError::NoSensorModel`] for a depth mode without a noise model.
    pub fn sensor_maps(
        &self,
        frame: &FrameInput,
        mode: Mode,
        sensor: Option<&SensorNoise>,
        described: Option<&str>,
        table: Option<&IntervalTable>,
    ) -> Result<SensorMaps, PipelineError> {
        if mode == Mode::Rgb {
            if let (Some(table), Some(depth)) = (table, self.depth_m()) {
                return Ok(self.interval_maps(table, None, &depth));
            }
        }
        let (Some(depth_m), Some(normals), false) =
            (&frame.depth_m, self.normals(), mode == Mode::Rgb)
        else {
            let mode = if mode == Mode::Rgb {
                "rgb"
            } else {
                "end-to-end"
            };
            return Err(PipelineError::NoSensorDepth { mode });
        };
        let Some(sensor) = sensor else {
            return Err(PipelineError::NoSensorModel {
                described: described.map(str::to_owned),
            });
        };
        // The terrain estimate's margin is its uncertainty; its calibration is its noise model
        // (a table fitted on the spec's readings does not apply to it).
        let (uncertainty_m, table) = match &self.working.terrain_uncertainty_m {
            Some(u) => (self.full_size(u, f64::NAN), None),
            None => (
                self.spec_uncertainty(frame, depth_m, &normals, sensor)?,
                table,
            ),
        };
        if let Some(table) = table {
            return Ok(self.interval_maps(table, Some(uncertainty_m), depth_m));
        }
        let rule = ThreeStateRule {
            max_roughness_m: self.working.limits.max_roughness_m,
            ..ThreeStateRule::default()
        };
        // Without gravity the slope cannot be judged: the roughness alone decides hazards, and
        // what it would pass becomes unknown.
        let binary = match self.working.up_in_cam {
            Some(_) => self.traversable(),
            None => self.within(&Traversability {
                max_slope_rad: std::f64::consts::FRAC_PI_2,
                ..self.working.limits
            }),
        };
        let mut traversal = rule.map(&self.roughness_m, &uncertainty_m, &binary);
        self.unknown_without_gravity(&mut traversal);
        Ok(SensorMaps {
            uncertainty_m,
            interval_m: None,
            traversal,
        })
    }

    /// The spec's noise model as an uncertainty map (NaN where there is no roughness).
    fn spec_uncertainty(
        &self,
        frame: &FrameInput,
        depth_m: &Grid<f64>,
        normals: &Grid<Vec3>,
        sensor: &SensorNoise,
    ) -> Result<Grid<f64>, PipelineError> {
        let (w, h) = depth_m.size();
        let k = match frame.intrinsics {
            Some(k) => k,
            None => Intrinsics::from_hfov(w, h, DEFAULT_HFOV_DEG)?,
        };
        let mut u = uncertainty_map(depth_m, &k, normals, sensor, &AnnotateConfig::default());
        for (u, r) in u.as_mut_slice().iter_mut().zip(self.roughness_m.as_slice()) {
            if !r.is_finite() {
                *u = f64::NAN;
            }
        }
        Ok(u)
    }

    /// The maps of a calibration table: its second feature is `uncertainty_m` (depth modes)
    /// or `depth_m` (the sensor's, or the depth net's in `rgb`).
    fn interval_maps(
        &self,
        table: &IntervalTable,
        uncertainty_m: Option<Grid<f64>>,
        depth_m: &Grid<f64>,
    ) -> SensorMaps {
        let second = match (table.second_axis, &uncertainty_m) {
            (SecondAxis::Uncertainty, Some(u)) => u,
            _ => depth_m,
        };
        let feature = table.feature(&self.roughness_m, depth_m);
        let (lo, hi) = table.maps(&self.roughness_m, &feature, second);
        let ok = self.slope_ok();
        let t = self.working.limits.max_roughness_m;
        let (w, h) = lo.size();
        let mut traversal = Grid::from_fn(w, h, |x, y| {
            interval::classify(lo[(x, y)], hi[(x, y)], t, ok[(x, y)])
        });
        self.unknown_without_gravity(&mut traversal);
        let uncertainty_m = uncertainty_m
            .unwrap_or_else(|| Grid::from_fn(w, h, |x, y| 0.5 * (hi[(x, y)] - lo[(x, y)])));
        SensorMaps {
            uncertainty_m,
            interval_m: Some((lo, hi)),
            traversal,
        }
    }

    /// Pixels whose slope is within the threshold (every pixel with roughness when there are
    /// no normals, or gravity is unknown: [`unknown_without_gravity`](Self::unknown_without_gravity)
    /// then turns traversable into unknown).
    fn slope_ok(&self) -> Grid<bool> {
        let gravity_known = self.working.up_in_cam.is_some();
        self.within(&Traversability {
            max_roughness_m: f64::INFINITY,
            max_slope_rad: if gravity_known {
                self.working.limits.max_slope_rad
            } else {
                std::f64::consts::FRAC_PI_2
            },
        })
    }

    /// With gravity unknown and a slope threshold below 90°, no pixel can be called
    /// traversable: those the roughness alone would pass become unknown.
    fn unknown_without_gravity(&self, traversal: &mut Grid<Traversal>) {
        if self.slope_without_gravity(&self.working.limits) {
            for t in traversal.as_mut_slice() {
                if *t == Traversal::Traversable {
                    *t = Traversal::Unknown;
                }
            }
        }
    }
}
