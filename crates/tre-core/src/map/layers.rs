//! The map's layers, as read by people and planners: one `side × side` float32 grid per layer,
//! row-major, column 0 at the window's smallest x (west), row 0 at its largest y (north), so that
//! a layer saved as an image looks down on the map with +y up (docs/map.md).

use super::GridMap;
use crate::geometry::Grid;
use crate::roughness::traversal::Traversal;

/// The layer names, in the order [`Layers::all`] gives them.
pub const LAYER_NAMES: [&str; 9] = [
    "elevation",
    "variance",
    "count",
    "roughness",
    "slope",
    "step",
    "score",
    "traversal",
    "last_update",
];

/// The unit of each layer, in [`LAYER_NAMES`] order.
pub const LAYER_UNITS: [&str; 9] = [
    "m",
    "m^2",
    "measurements",
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
}

impl Default for MapLimits {
    fn default() -> Self {
        Self {
            max_roughness_m: 0.05,
            max_slope_rad: 20f64.to_radians(),
            max_step_m: 0.05,
            min_count: 3,
            max_sigma_m: 0.02,
        }
    }
}

/// Every layer of a map window (NaN: no data; `traversal` 0 unknown, 1 traversable, 2 hazard).
#[derive(Debug, Clone, PartialEq)]
pub struct Layers {
    /// Height in the map frame, metres.
    pub elevation: Grid<f32>,
    /// Its variance, m².
    pub variance: Grid<f32>,
    /// Measurements fused.
    pub count: Grid<f32>,
    /// Mean roughness, metres.
    pub roughness: Grid<f32>,
    /// Slope of the height surface, degrees.
    pub slope: Grid<f32>,
    /// Largest height difference to a seen 8-neighbour, metres.
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
    pub fn all(&self) -> [&Grid<f32>; 9] {
        [
            &self.elevation,
            &self.variance,
            &self.count,
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
    /// The map's layers under `limits`. A cell with fewer than `min_count` measurements or a
    /// height σ above `max_sigma_m` is unknown; else a hazard when its roughness, slope or step
    /// reaches a limit, traversable otherwise. Slope comes from the central differences of
    /// the neighbours' heights (one-sided at a gap), step from the largest difference to a seen
    /// 8-neighbour.
    pub fn layers(&self, limits: &MapLimits) -> Layers {
        let side = self.cfg.side;
        let nan = |_: usize, _: usize| f32::NAN;
        let mut out = Layers {
            elevation: Grid::from_fn(side, side, nan),
            variance: Grid::from_fn(side, side, nan),
            count: Grid::from_fn(side, side, |_, _| 0.0),
            roughness: Grid::from_fn(side, side, nan),
            slope: Grid::from_fn(side, side, nan),
            step: Grid::from_fn(side, side, nan),
            score: Grid::from_fn(side, side, nan),
            traversal: Grid::from_fn(side, side, |_, _| 0.0),
            last_update: Grid::from_fn(side, side, nan),
        };
        let height = |c: isize, r: isize| -> Option<f64> {
            if c < 0 || r < 0 || c >= side as isize || r >= side as isize {
                return None;
            }
            let cell = self.at(c as usize, r as usize);
            (cell.count > 0 && cell.height_m.is_finite()).then_some(f64::from(cell.height_m))
        };
        for row in 0..side {
            for col in 0..side {
                let cell = self.at(col, row);
                if cell.count == 0 {
                    continue;
                }
                let (c, r) = (col as isize, row as isize);
                let h = f64::from(cell.height_m);
                out.elevation[(col, row)] = cell.height_m;
                out.variance[(col, row)] = cell.var_m2;
                out.count[(col, row)] = cell.count as f32;
                out.roughness[(col, row)] = cell.roughness_m;
                out.last_update[(col, row)] = cell.last_s as f32;
                let slope = slope_at(&height, (c, r), h, self.cfg.cell_m);
                let step = step_at(&height, (c, r), h);
                out.slope[(col, row)] = slope.map_or(f32::NAN, |s| s.to_degrees() as f32);
                out.step[(col, row)] = step as f32;
                let (score, state) = judge(cell, slope, step, limits);
                out.score[(col, row)] = score;
                out.traversal[(col, row)] = f32::from(state as u8);
            }
        }
        out
    }
}

/// A seen cell's score and three-state value from its roughness, `slope` (radians) and `step`
/// (metres; NaN parts, no roughness or no neighbour, do not count against it).
fn judge(
    cell: &super::Cell,
    slope: Option<f64>,
    step: f64,
    limits: &MapLimits,
) -> (f32, Traversal) {
    let rough = f64::from(cell.roughness_m);
    let parts = [
        rough / limits.max_roughness_m,
        slope.map_or(f64::NAN, |s| s / limits.max_slope_rad),
        step / limits.max_step_m,
    ];
    let worst = parts
        .iter()
        .copied()
        .filter(|v| v.is_finite())
        .fold(0.0f64, f64::max);
    let judged = cell.count >= limits.min_count
        && f64::from(cell.var_m2).sqrt() <= limits.max_sigma_m
        && rough.is_finite();
    let state = if !judged {
        Traversal::Unknown
    } else if worst >= 1.0 {
        Traversal::Hazard
    } else {
        Traversal::Traversable
    };
    ((1.0 - worst).clamp(0.0, 1.0) as f32, state)
}

/// The largest height difference from `h` to a seen 8-neighbour of `(c, r)` (NaN: none seen).
fn step_at(height: &impl Fn(isize, isize) -> Option<f64>, (c, r): (isize, isize), h: f64) -> f64 {
    crate::geometry::NEIGHBOURS_8
        .iter()
        .filter_map(|&(dc, dr)| height(c + dc as isize, r + dr as isize))
        .map(|n| (n - h).abs())
        .fold(f64::NAN, f64::max)
}

/// Slope at `(c, r)` of height `h` from its neighbours' heights: central differences where both
/// neighbours are seen, one-sided where one is; `None` without any along an axis.
fn slope_at(
    height: &impl Fn(isize, isize) -> Option<f64>,
    (c, r): (isize, isize),
    h: f64,
    cell_m: f64,
) -> Option<f64> {
    let grad = |a: Option<f64>, b: Option<f64>| -> Option<f64> {
        match (a, b) {
            (Some(a), Some(b)) => Some((b - a) / (2.0 * cell_m)),
            (Some(a), None) => Some((h - a) / cell_m),
            (None, Some(b)) => Some((b - h) / cell_m),
            (None, None) => None,
        }
    };
    let gx = grad(height(c - 1, r), height(c + 1, r))?;
    let gy = grad(height(c, r + 1), height(c, r - 1))?;
    Some(gx.hypot(gy).atan())
}
