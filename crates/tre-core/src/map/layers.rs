//! The map's layers, as read by people and planners: one `side × side` float32 grid per layer,
//! row-major, column 0 at the window's smallest x (west), row 0 at its largest y (north), so that
//! a layer saved as an image looks down on the map with +y up (docs/map.md).

use super::surface::{Ground, Surface};
use super::{Cell, GridMap};
use crate::geometry::Grid;
use crate::roughness::traversal::Traversal;

/// The layer names, in the order [`Layers::all`] gives them.
pub const LAYER_NAMES: [&str; 11] = [
    "elevation",
    "variance",
    "count",
    "upper",
    "clearance",
    "roughness",
    "slope",
    "step",
    "score",
    "traversal",
    "last_update",
];

/// The unit of each layer, in [`LAYER_NAMES`] order.
pub const LAYER_UNITS: [&str; 11] = [
    "m",
    "m^2",
    "measurements",
    "m",
    "m",
    "m",
    "degrees",
    "m",
    "0 to 1",
    "0 unknown, 1 traversable, 2 hazard",
    "s",
];

/// Thresholds of the map's traversability.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MapLimits {
    /// Largest roughness a robot drives over, metres (default 0.05).
    pub max_roughness_m: f64,
    /// Steepest slope, radians (default 20°).
    pub max_slope_rad: f64,
    /// Highest step to a neighbouring cell, metres (default 0.05).
    pub max_step_m: f64,
    /// Fewest measurements for a cell to be judged (default 3): fewer is unknown.
    pub min_count: u32,
    /// Largest height standard deviation for a cell to be judged, metres (default 0.02).
    pub max_sigma_m: f64,
    /// Least clearance under a surface above the ground, metres (default 0: not judged): a
    /// cell whose upper surface is lower above its ground is a hazard (a table top, an
    /// overhang the robot does not fit under).
    pub min_clearance_m: f64,
}

impl Default for MapLimits {
    fn default() -> Self {
        Self {
            max_roughness_m: 0.05,
            max_slope_rad: 20f64.to_radians(),
            max_step_m: 0.05,
            min_count: 3,
            max_sigma_m: 0.02,
            min_clearance_m: 0.0,
        }
    }
}

/// Every layer of a map window (NaN: no data; `traversal` 0 unknown, 1 traversable, 2 hazard).
#[derive(Debug, Clone, PartialEq)]
pub struct Layers {
    /// Height of the ground (the lowest surface seen) in the map frame, metres.
    pub elevation: Grid<f32>,
    /// Its variance (fused and correlated parts), m².
    pub variance: Grid<f32>,
    /// Measurements fused into the ground.
    pub count: Grid<f32>,
    /// Height of the highest surface seen above the ground, metres.
    pub upper: Grid<f32>,
    /// The upper surface's height above the ground, metres.
    pub clearance: Grid<f32>,
    /// Roughness of the fused ground: the scatter of the neighbourhood's heights about their
    /// plane, less what the heights' variances explain, metres.
    pub roughness: Grid<f32>,
    /// Slope of that plane, degrees.
    pub slope: Grid<f32>,
    /// Height above the lowest seen 8-neighbour, less two σ of the difference, metres.
    pub step: Grid<f32>,
    /// Traversability score, 0 (at or beyond a limit) to 1 (flat, level, no step).
    pub score: Grid<f32>,
    /// Three-state traversability.
    pub traversal: Grid<f32>,
    /// Time of the last fused measurement, seconds.
    pub last_update: Grid<f32>,
}

impl Layers {
    /// The layers in [`LAYER_NAMES`] order.
    pub fn all(&self) -> [&Grid<f32>; 11] {
        [
            &self.elevation,
            &self.variance,
            &self.count,
            &self.upper,
            &self.clearance,
            &self.roughness,
            &self.slope,
            &self.step,
            &self.score,
            &self.traversal,
            &self.last_update,
        ]
    }
}

impl GridMap {
    /// The map's layers under `limits`. A cell with fewer than `min_count` measurements, a
    /// height σ above `max_sigma_m` or no roughness (too few seen neighbours on its surface)
    /// and no step beyond the limit is unknown;
    /// else a hazard when its roughness, slope or step reaches a limit, or its clearance is
    /// under `min_clearance_m`, traversable otherwise. Roughness and slope come from the plane
    /// of the fused ground heights within [`MapConfig::roughness_radius_m`] of the cell
    /// (`Ground::surface`), the step from its lowest seen 8-neighbour (`Ground::step`).
    ///
    /// [`MapConfig::roughness_radius_m`]: super::MapConfig::roughness_radius_m
    pub fn layers(&self, limits: &MapLimits) -> Layers {
        let side = self.cfg.side;
        let grid = |v: f32| Grid::from_fn(side, side, move |_, _| v);
        let mut out = Layers {
            elevation: grid(f32::NAN),
            variance: grid(f32::NAN),
            count: grid(0.0),
            upper: grid(f32::NAN),
            clearance: grid(f32::NAN),
            roughness: grid(f32::NAN),
            slope: grid(f32::NAN),
            step: grid(f32::NAN),
            score: grid(f32::NAN),
            traversal: grid(0.0),
            last_update: grid(f32::NAN),
        };
        let ground = self.ground();
        let radius = ((self.cfg.roughness_radius_m / self.cfg.cell_m).round() as usize).max(1);
        for row in 0..side {
            for col in 0..side {
                let cell = self.at(col, row);
                if cell.count == 0 {
                    continue;
                }
                let at = (col, row);
                out.elevation[at] = cell.height_m;
                out.variance[at] = cell.total_var_m2();
                out.count[at] = cell.count as f32;
                out.upper[at] = if cell.upper_count > 0 {
                    cell.upper_m
                } else {
                    f32::NAN
                };
                out.clearance[at] = cell.clearance_m();
                out.last_update[at] = cell.last_s as f32;
                let surface = ground.surface(at, radius, (limits.max_step_m, limits.max_slope_rad));
                let step = ground.step(at);
                out.roughness[at] = surface.map_or(f32::NAN, |s| s.roughness_m as f32);
                out.slope[at] = surface.map_or(f32::NAN, |s| s.slope_rad.to_degrees() as f32);
                out.step[at] = step as f32;
                let (score, state) = judge(cell, surface, step, limits);
                out.score[at] = score;
                out.traversal[at] = f32::from(state as u8);
            }
        }
        out
    }

    /// The fused ground heights and variances in the layers' layout.
    fn ground(&self) -> Ground {
        let side = self.cfg.side;
        let mut g = Ground {
            side,
            cell_m: self.cfg.cell_m,
            height: vec![f64::NAN; side * side],
            var: vec![f64::NAN; side * side],
        };
        for row in 0..side {
            for col in 0..side {
                let cell = self.at(col, row);
                if cell.count > 0 && cell.height_m.is_finite() {
                    g.height[row * side + col] = f64::from(cell.height_m);
                    g.var[row * side + col] = f64::from(cell.total_var_m2());
                }
            }
        }
        g
    }
}

/// A seen cell's score and three-state value from its `surface` (roughness and slope), `step`
/// (metres; NaN, no neighbour, does not count against it) and clearance.
fn judge(cell: &Cell, surface: Option<Surface>, step: f64, limits: &MapLimits) -> (f32, Traversal) {
    let rough = surface.map_or(f64::NAN, |s| s.roughness_m);
    let clearance = f64::from(cell.clearance_m());
    let low = limits.min_clearance_m > 0.0 && clearance < limits.min_clearance_m;
    let parts = [
        rough / limits.max_roughness_m,
        surface.map_or(f64::NAN, |s| s.slope_rad / limits.max_slope_rad),
        step / limits.max_step_m,
    ];
    let worst = parts
        .iter()
        .copied()
        .filter(|v| v.is_finite())
        .fold(if low { 1.0 } else { 0.0 }, f64::max);
    // A cell too small a surface for a plane (a post, one raised cell) is judged by its step.
    let judged = cell.count >= limits.min_count
        && f64::from(cell.total_var_m2()).sqrt() <= limits.max_sigma_m
        && (rough.is_finite() || step >= limits.max_step_m);
    let state = if !judged {
        Traversal::Unknown
    } else if worst >= 1.0 {
        Traversal::Hazard
    } else {
        Traversal::Traversable
    };
    ((1.0 - worst).clamp(0.0, 1.0) as f32, state)
}
