//! The map's settings, one set read by `tre map`, the stream and `tre ros2` (docs/map.md): the
//! grid, the ranges, the fusion and the traversability limits, with an indoor and an outdoor
//! preset. A settings file (TOML, units in the key names) starts from a preset and changes
//! what it names; a key it does not know is an error, not a silent default.

use serde::Deserialize;

use super::{MapConfig, MapLimits};

/// A preset of the map's settings.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize, Default)]
#[serde(rename_all = "lowercase")]
pub enum MapPreset {
    /// A hand-held or indoor robot's camera: 4 cm cells, an 8 m window, points to 4 m.
    #[default]
    Indoor,
    /// A robot on roads and paths: 10 cm cells, a 40 m window, points from 1 to 20 m.
    Outdoor,
}

/// Every setting of a map.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MapParams {
    /// Grid, ranges and fusion.
    pub config: MapConfig,
    /// Traversability limits.
    pub limits: MapLimits,
}

impl MapParams {
    /// The settings of `preset`.
    ///
    /// ```
    /// use tre_core::map::{MapParams, MapPreset};
    /// let p = MapParams::preset(MapPreset::Outdoor);
    /// assert_eq!((p.config.cell_m, p.config.side), (0.1, 400));
    /// ```
    #[must_use]
    pub fn preset(preset: MapPreset) -> Self {
        match preset {
            MapPreset::Indoor => Self {
                config: MapConfig::default(),
                limits: MapLimits::default(),
            },
            MapPreset::Outdoor => Self {
                config: MapConfig {
                    cell_m: 0.10,
                    side: 400,
                    min_range_m: 1.0,
                    max_range_m: 20.0,
                    surface_band_m: 0.10,
                    height_floor_m: 0.01,
                    roughness_radius_m: 0.3,
                    ..MapConfig::default()
                },
                limits: MapLimits {
                    max_step_m: 0.10,
                    max_sigma_m: 0.05,
                    ..MapLimits::default()
                },
            },
        }
    }

    /// These settings with the flags a command was given (`--cell-cm`, `--size-m`,
    /// `--max-range-m`, in metres here): a new cell side keeps the window's size.
    ///
    /// # Errors
    ///
    /// [`ParamsError`] for a value out of its range.
    pub fn with_flags(
        mut self,
        cell_m: Option<f64>,
        size_m: Option<f64>,
        max_range_m: Option<f64>,
    ) -> Result<Self, ParamsError> {
        let c = &mut self.config;
        let size_m = size_m.unwrap_or(c.side as f64 * c.cell_m);
        set(&mut c.cell_m, cell_m);
        c.side = (size_m / c.cell_m).round().max(0.0) as usize;
        set(&mut c.max_range_m, max_range_m);
        self.check()?;
        Ok(self)
    }

    /// The settings a file states: its `preset` (indoor when it names none) changed by every
    /// key it gives, then checked.
    ///
    /// # Errors
    ///
    /// [`ParamsError`] for a value out of its range.
    pub fn from_file(file: &MapParamsFile) -> Result<Self, ParamsError> {
        let mut p = Self::preset(file.preset.unwrap_or_default());
        let (c, l) = (&mut p.config, &mut p.limits);
        let g = &file.grid;
        set(&mut c.cell_m, g.cell_m);
        if let Some(size) = g.size_m {
            c.side = (size / c.cell_m).round().max(0.0) as usize;
        }
        set(&mut c.min_range_m, file.range.min_m);
        set(&mut c.max_range_m, file.range.max_m);
        let f = &file.fusion;
        set(&mut c.process_var_per_s, f.process_var_m2_per_s);
        set(&mut c.outlier_sigmas, f.outlier_sigmas);
        set(&mut c.restart_after, f.restart_after);
        set(&mut c.surface_band_m, f.surface_band_m);
        set(&mut c.height_floor_m, f.height_floor_m);
        let t = &file.traversability;
        set(&mut c.roughness_radius_m, t.roughness_radius_m);
        set(&mut l.max_roughness_m, t.max_roughness_m);
        set(&mut l.max_slope_rad, t.max_slope_deg.map(f64::to_radians));
        set(&mut l.max_step_m, t.max_step_m);
        set(&mut l.min_count, t.min_count);
        set(&mut l.max_sigma_m, t.max_sigma_m);
        set(&mut l.min_clearance_m, t.min_clearance_m);
        p.check()?;
        Ok(p)
    }

    /// Every value in its range.
    ///
    /// # Errors
    ///
    /// [`ParamsError::OutOfRange`] naming the first value that is not.
    pub fn check(&self) -> Result<(), ParamsError> {
        let (c, l) = (&self.config, &self.limits);
        let (p, nn) = (Must::Positive, Must::NonNegative);
        let values = [
            ("grid.cell_m", c.cell_m, p),
            ("range.min_m", c.min_range_m, nn),
            ("range.max_m", c.max_range_m, p),
            ("fusion.process_var_m2_per_s", c.process_var_per_s, nn),
            ("fusion.outlier_sigmas", c.outlier_sigmas, p),
            ("fusion.surface_band_m", c.surface_band_m, p),
            ("fusion.height_floor_m", c.height_floor_m, nn),
            ("traversability.roughness_radius_m", c.roughness_radius_m, p),
            ("traversability.max_roughness_m", l.max_roughness_m, p),
            ("traversability.max_step_m", l.max_step_m, p),
            ("traversability.max_sigma_m", l.max_sigma_m, p),
            ("traversability.min_clearance_m", l.min_clearance_m, nn),
        ];
        for (key, value, must) in values {
            must.check(key, value)?;
        }
        self.check_others()
    }

    /// The values whose range is not a sign.
    fn check_others(&self) -> Result<(), ParamsError> {
        let (c, l) = (&self.config, &self.limits);
        let out = |key, value, range| Err(ParamsError::OutOfRange { key, value, range });
        if !(1..=8192).contains(&c.side) {
            return out("grid.size_m", c.side as f64 * c.cell_m, "1 to 8192 cells");
        }
        if !(c.max_range_m > c.min_range_m) {
            return out("range.max_m", c.max_range_m, "above range.min_m");
        }
        let slope = l.max_slope_rad.to_degrees();
        if !(slope > 0.0 && slope < 90.0) {
            return out(
                "traversability.max_slope_deg",
                slope,
                "above 0 and below 90",
            );
        }
        if c.restart_after == 0 {
            return out("fusion.restart_after", 0.0, "1 or more");
        }
        Ok(())
    }
}

/// What a value must be.
#[derive(Debug, Clone, Copy)]
enum Must {
    Positive,
    NonNegative,
}

impl Must {
    fn check(self, key: &'static str, value: f64) -> Result<(), ParamsError> {
        let (ok, range) = match self {
            Self::Positive => (value.is_finite() && value > 0.0, "positive"),
            Self::NonNegative => (value.is_finite() && value >= 0.0, "0 or more"),
        };
        if ok {
            Ok(())
        } else {
            Err(ParamsError::OutOfRange { key, value, range })
        }
    }
}

fn set<T>(field: &mut T, value: Option<T>) {
    if let Some(v) = value {
        *field = v;
    }
}

/// A value out of its range.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum ParamsError {
    /// The key, its value and what it must be.
    #[error("map settings: {key} = {value} must be {range}")]
    OutOfRange {
        /// The key, `section.name`.
        key: &'static str,
        /// Its value.
        value: f64,
        /// What it must be.
        range: &'static str,
    },
}

/// A map settings file as written: every key optional, none unknown.
#[derive(Debug, Clone, Default, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MapParamsFile {
    /// The preset the file starts from (default indoor).
    pub preset: Option<MapPreset>,
    /// `[grid]`.
    #[serde(default)]
    pub grid: GridKeys,
    /// `[range]`.
    #[serde(default)]
    pub range: RangeKeys,
    /// `[fusion]`.
    #[serde(default)]
    pub fusion: FusionKeys,
    /// `[traversability]`.
    #[serde(default)]
    pub traversability: TraversabilityKeys,
}

/// `[grid]`: the cells and the window.
#[derive(Debug, Clone, Default, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct GridKeys {
    /// Side of a cell, metres.
    pub cell_m: Option<f64>,
    /// Side of the square window, metres.
    pub size_m: Option<f64>,
}

/// `[range]`: which points of a frame are fused, by depth.
#[derive(Debug, Clone, Default, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RangeKeys {
    /// Nearest depth, metres.
    pub min_m: Option<f64>,
    /// Farthest depth, metres.
    pub max_m: Option<f64>,
}

/// `[fusion]`: the Kalman filter and the surfaces of a cell.
#[derive(Debug, Clone, Default, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct FusionKeys {
    /// Process noise of a height, m² per second.
    pub process_var_m2_per_s: Option<f64>,
    /// Innovations beyond this many σ are not the same surface.
    pub outlier_sigmas: Option<f64>,
    /// Measurements below the ground in a row after which it restarts.
    pub restart_after: Option<u32>,
    /// Points within this height of a cell's lowest are one surface, metres.
    pub surface_band_m: Option<f64>,
    /// Least height σ of a measurement, metres.
    pub height_floor_m: Option<f64>,
}

/// `[traversability]`: how the fused ground is read and judged.
#[derive(Debug, Clone, Default, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct TraversabilityKeys {
    /// Radius of the neighbourhood a cell's roughness and slope come from, metres.
    pub roughness_radius_m: Option<f64>,
    /// Largest roughness, metres.
    pub max_roughness_m: Option<f64>,
    /// Steepest slope, degrees.
    pub max_slope_deg: Option<f64>,
    /// Highest step, metres.
    pub max_step_m: Option<f64>,
    /// Fewest measurements for a cell to be judged.
    pub min_count: Option<u32>,
    /// Largest height σ for a cell to be judged, metres.
    pub max_sigma_m: Option<f64>,
    /// Least clearance under a surface above the ground, metres (0: not judged).
    pub min_clearance_m: Option<f64>,
}
