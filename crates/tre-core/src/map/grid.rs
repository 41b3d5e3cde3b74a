//! The map's window: a ring buffer of cells that follows the robot, and the fusion of one
//! frame's points into it (docs/map.md).

use nalgebra::Matrix3;

use super::{Cell, Fused, MapConfig, MapError, MapFrame, Pose};
use crate::geometry::{is_valid_point, PointMap, Vec3};
use crate::roughness::noise::SensorNoise;

/// What a frame did to the map.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct FuseStats {
    /// Points that fell in the map.
    pub points: usize,
    /// Cells measured.
    pub cells: usize,
    /// Cells started (first seen or restarted).
    pub started: usize,
    /// Cells whose ground measurement was below the ground beyond the bound (an outlier).
    pub outliers: usize,
    /// Cells whose ground measurement was a surface above the ground.
    pub above: usize,
}

/// A gravity-aligned grid map fused over frames.
#[derive(Debug, Clone)]
pub struct GridMap {
    pub(super) cfg: MapConfig,
    frame: MapFrame,
    /// World cell index of the window's lower-left cell.
    origin: (i64, i64),
    /// Ring buffer, `side × side`, cell (ix, iy) at `(ix mod side, iy mod side)`.
    pub(super) cells: Vec<Cell>,
    /// Per-frame sums, one per cell (reused).
    acc: Vec<Acc>,
    /// The frame's points in the map (reused).
    landed: Vec<Landed>,
    /// What the sensor's stated height variance is multiplied by, learnt from the map's own
    /// innovations ([`GridMap::noise_scale`]).
    noise_scale: f64,
}

/// One cell's sums over a frame's points (reused from frame to frame).
#[derive(Debug, Clone, Copy)]
struct Acc {
    /// Points, the sum of their height variances and of the correlated part of it.
    n: u32,
    var_sum: f64,
    corr_sum: f64,
    /// Lowest and highest point.
    z_min: f64,
    z_max: f64,
    /// The low cluster (within the band of the lowest point): sum, count, variance sum.
    lo: (f64, u32, f64),
    /// The high cluster (within the band of the highest point, when apart from the low one).
    hi: (f64, u32, f64),
}

impl Default for Acc {
    fn default() -> Self {
        Self {
            n: 0,
            var_sum: 0.0,
            corr_sum: 0.0,
            z_min: f64::INFINITY,
            z_max: f64::NEG_INFINITY,
            lo: (0.0, 0, 0.0),
            hi: (0.0, 0, 0.0),
        }
    }
}

/// The median of χ² with one degree of freedom: a normalised innovation's median when the
/// stated noise is right.
const CHI2_1_MEDIAN: f64 = 0.455;
/// Cells seen before that a frame must measure for its innovations to rescale the noise.
const MIN_RESCALE_CELLS: usize = 20;
/// The largest noise scale (a height σ 100 times the stated).
const MAX_NOISE_SCALE: f64 = 1e4;

/// The window's ring-buffer layout for one frame: [`GridMap::slot`] without a division per
/// point (the origin's place in the ring computed once).
#[derive(Debug, Clone, Copy)]
struct Ring {
    origin: (i64, i64),
    side: i64,
    /// The origin's column and row in the ring.
    start: (i64, i64),
}

impl Ring {
    fn of(map: &GridMap) -> Self {
        let side = map.cfg.side as i64;
        Self {
            origin: map.origin,
            side,
            start: (map.origin.0.rem_euclid(side), map.origin.1.rem_euclid(side)),
        }
    }

    /// Ring-buffer slot of world cell `(ix, iy)`, if it is in the window.
    fn slot(&self, ix: i64, iy: i64) -> Option<usize> {
        let (dx, dy) = (ix - self.origin.0, iy - self.origin.1);
        if !(0..self.side).contains(&dx) || !(0..self.side).contains(&dy) {
            return None;
        }
        let wrap = |v: i64| if v >= self.side { v - self.side } else { v };
        Some((wrap(self.start.1 + dy) * self.side + wrap(self.start.0 + dx)) as usize)
    }
}

/// One point of a frame in the map: its cell's slot, its height and the height's variance.
#[derive(Debug, Clone, Copy)]
struct Landed {
    slot: u32,
    z: f32,
    var: f32,
}

impl GridMap {
    /// An empty map centred on the map-frame point `(x, y)`.
    pub fn new(cfg: MapConfig, frame: MapFrame, centre: (f64, f64)) -> Result<Self, MapError> {
        if !(cfg.cell_m.is_finite() && cfg.cell_m > 0.0) || cfg.side == 0 || cfg.side > 8192 {
            return Err(MapError::BadGrid {
                cell_m: cfg.cell_m,
                side: cfg.side,
            });
        }
        let n = cfg.side * cfg.side;
        let mut map = Self {
            cfg,
            frame,
            origin: (0, 0),
            cells: vec![Cell::default(); n],
            acc: vec![Acc::default(); n],
            landed: Vec::new(),
            noise_scale: 1.0,
        };
        map.origin = map.origin_for(centre);
        Ok(map)
    }

    /// An empty map in `frame` whose window is centred under the camera at `pose` (how a map
    /// starts at its first frame).
    pub fn under(cfg: MapConfig, frame: MapFrame, pose: &Pose) -> Result<Self, MapError> {
        let c = frame.map_from_world * pose.translation;
        Self::new(cfg, frame, (c.x, c.y))
    }

    /// The configuration.
    pub fn config(&self) -> &MapConfig {
        &self.cfg
    }

    /// The map frame.
    pub fn frame(&self) -> &MapFrame {
        &self.frame
    }

    /// World cell index of the window's lower-left cell (x, y).
    pub fn origin(&self) -> (i64, i64) {
        self.origin
    }

    /// Memory the map holds, bytes: cells, the frame's sums (both fixed by the side) and the
    /// frame's points (fixed by the largest frame seen).
    pub fn memory_bytes(&self) -> usize {
        self.cells.len() * (std::mem::size_of::<Cell>() + std::mem::size_of::<Acc>())
            + self.landed.capacity() * std::mem::size_of::<Landed>()
    }

    /// The map frame turned to `frame` (a small correction of its level): every seen cell's
    /// heights are moved to the new frame's z at the cell's place (the horizontal shift, the
    /// tilt times the height, is left out: under a cell for a tilt of a degree or two).
    pub(crate) fn relevel(&mut self, frame: MapFrame) {
        let turn = frame.map_from_world * self.frame.map_from_world.transpose();
        let side = self.cfg.side;
        for row in 0..side {
            for col in 0..side {
                let (x, y) = self.cell_centre(col, row);
                let i = self.index(col, row);
                let cell = &mut self.cells[i];
                for h in [&mut cell.height_m, &mut cell.upper_m] {
                    if h.is_finite() {
                        *h = (turn * Vec3::new(x, y, f64::from(*h))).z as f32;
                    }
                }
            }
        }
        self.frame = frame;
    }

    /// The map-frame centre (x, y) of the cell at window position `(col, row)`.
    pub fn cell_centre(&self, col: usize, row: usize) -> (f64, f64) {
        let ix = self.origin.0 + col as i64;
        let iy = self.origin.1 + (self.cfg.side - 1 - row) as i64;
        (
            (ix as f64 + 0.5) * self.cfg.cell_m,
            (iy as f64 + 0.5) * self.cfg.cell_m,
        )
    }

    fn origin_for(&self, (x, y): (f64, f64)) -> (i64, i64) {
        let half = (self.cfg.side / 2) as i64;
        (self.cell_of(x) - half, self.cell_of(y) - half)
    }

    fn cell_of(&self, v: f64) -> i64 {
        (v / self.cfg.cell_m).floor() as i64
    }

    /// Ring-buffer slot of world cell `(ix, iy)`, if it is in the window.
    pub(super) fn slot(&self, ix: i64, iy: i64) -> Option<usize> {
        let side = self.cfg.side as i64;
        let (dx, dy) = (ix - self.origin.0, iy - self.origin.1);
        if !(0..side).contains(&dx) || !(0..side).contains(&dy) {
            return None;
        }
        Some((iy.rem_euclid(side) * side + ix.rem_euclid(side)) as usize)
    }

    /// The cell at world cell `(ix, iy)`, if in the window.
    pub fn cell(&self, ix: i64, iy: i64) -> Option<&Cell> {
        self.slot(ix, iy).map(|i| &self.cells[i])
    }

    /// Moves the window so that it is centred on the map-frame point `(x, y)`: the cells that
    /// leave it are cleared (only they are touched), the others keep their state in place.
    /// Returns the cells cleared.
    pub fn recentre(&mut self, centre: (f64, f64)) -> usize {
        let new = self.origin_for(centre);
        if new == self.origin {
            return 0;
        }
        let side = self.cfg.side as i64;
        let old = self.origin;
        let mut cleared = 0;
        // World columns / rows in the old window but not the new one.
        let leaving = |o: i64, n: i64| -> Vec<i64> {
            (o..o + side)
                .filter(|v| !(n..n + side).contains(v))
                .collect()
        };
        let cols = leaving(old.0, new.0);
        let rows = leaving(old.1, new.1);
        if cols.len() as i64 >= side || rows.len() as i64 >= side {
            self.cells.fill(Cell::default());
            self.origin = new;
            return self.cells.len();
        }
        for &ix in &cols {
            for iy in old.1..old.1 + side {
                let i = (iy.rem_euclid(side) * side + ix.rem_euclid(side)) as usize;
                self.cells[i] = Cell::default();
                cleared += 1;
            }
        }
        for &iy in &rows {
            for ix in old.0..old.0 + side {
                if cols.contains(&ix) {
                    continue;
                }
                let i = (iy.rem_euclid(side) * side + ix.rem_euclid(side)) as usize;
                self.cells[i] = Cell::default();
                cleared += 1;
            }
        }
        self.origin = new;
        cleared
    }

    /// The camera's centre in the map frame for `pose`.
    pub fn camera_in_map(&self, pose: &Pose) -> Vec3 {
        self.frame.map_from_world * pose.translation
    }

    /// Fuses one frame: `points` in the camera frame (a back-projected depth map), the camera's
    /// `pose`, the time `t_s`, and the depth sensor's noise model `noise`. The
    /// window follows the camera (recentred when it is more than a quarter of the side from the
    /// centre).
    ///
    /// Per cell, the frame's points give a ground measurement, the mean height of the points
    /// within the band of the lowest one ([`MapConfig::surface_band_m`], or three height σ
    /// when more), and, when the highest point is more than two bands above the lowest, an
    /// upper-surface measurement, the mean of the points within the band of the highest. A
    /// point's height σ is σ_z turned along its ray into the vertical (σ_z·|Δh| / z: a far
    /// floor seen at a grazing angle is sharp in height); a measurement's variance is its
    /// points' mean height variance (the noise is correlated across neighbouring pixels, so
    /// the count does not shrink it) plus [`MapConfig::height_floor_m`]². The sensor's
    /// registration offset at the points' range ([`SensorNoise::registration_m`], accumulated
    /// LiDAR's) is kept apart as the cell's correlated variance ([`Cell::corr_var_m2`]).
    ///
    /// # Errors
    ///
    /// [`MapError::TooFar`] for a camera more than the window's side from its centre, and
    /// [`MapError::NothingSeen`] when no point lands in the map; the map is unchanged.
    pub fn fuse(
        &mut self,
        points: &PointMap,
        pose: &Pose,
        t_s: f64,
        noise: &SensorNoise,
    ) -> Result<FuseStats, MapError> {
        let cam = self.camera_in_map(pose);
        let side_m = self.cfg.side as f64 * self.cfg.cell_m;
        let centre = self.centre();
        let distance_m = ((cam.x - centre.0).powi(2) + (cam.y - centre.1).powi(2)).sqrt();
        if distance_m > side_m {
            return Err(MapError::TooFar {
                distance_m,
                limit_m: side_m,
            });
        }
        if distance_m > side_m / 4.0 {
            self.recentre((cam.x, cam.y));
        }
        let rot = self.frame.map_from_world * pose.rotation;
        let touched = self.land(points, (&rot, &cam), noise);
        if touched.is_empty() {
            return Err(MapError::NothingSeen);
        }
        self.cluster();
        self.rescale(&touched);
        let mut stats = FuseStats {
            points: self.landed.len(),
            ..FuseStats::default()
        };
        let (floor, scale) = (self.cfg.height_floor_m.powi(2), self.noise_scale);
        for i in touched {
            let a = std::mem::take(&mut self.acc[i]);
            let cell = &mut self.cells[i];
            stats.cells += 1;
            let n = f64::from(a.lo.1);
            let r = scale * a.lo.2 / n + floor;
            let fused = cell.fuse_height(a.lo.0 / n, r, t_s, &self.cfg);
            if fused != Fused::Above && fused != Fused::Outlier {
                cell.add_correlated(a.corr_sum / f64::from(a.n));
            }
            match fused {
                Fused::Started => stats.started += 1,
                Fused::Outlier => stats.outliers += 1,
                Fused::Above => stats.above += 1,
                Fused::Updated => {}
            }
            if a.hi.1 > 0 {
                let n = f64::from(a.hi.1);
                cell.fuse_upper(a.hi.0 / n, scale * a.hi.2 / n + floor, &self.cfg);
            }
        }
        Ok(stats)
    }

    /// Turns the frame's points (camera frame, turned by `rot` and moved by `trans` into the
    /// map frame) into [`Landed`] points of their cells, each cell's count, variance sum and
    /// height range summed; returns the cells touched.
    fn land(
        &mut self,
        points: &PointMap,
        (rot, trans): (&Matrix3<f64>, &Vec3),
        noise: &SensorNoise,
    ) -> Vec<usize> {
        let mut touched: Vec<usize> = Vec::new();
        self.landed.clear();
        let (lo, hi) = (self.cfg.min_range_m, self.cfg.max_range_m);
        let ring = Ring::of(self);
        let registered = noise.registration_m(1.0) > 0.0;
        for p in points.as_slice() {
            if !is_valid_point(p) || p.z > hi || p.z < lo {
                continue;
            }
            let v = rot * p;
            let m = v + trans;
            let Some(i) = ring.slot(self.cell_of(m.x), self.cell_of(m.y)) else {
                continue;
            };
            let var = (noise.sigma_z_m(p.z) * v.z / p.z).powi(2);
            let a = &mut self.acc[i];
            if a.n == 0 {
                touched.push(i);
            }
            a.n += 1;
            a.var_sum += var;
            if registered {
                a.corr_sum += noise.registration_m(p.norm()).powi(2);
            }
            a.z_min = a.z_min.min(m.z);
            a.z_max = a.z_max.max(m.z);
            self.landed.push(Landed {
                slot: i as u32,
                z: m.z as f32,
                var: var as f32,
            });
        }
        touched
    }

    /// What the sensor's stated height variance is multiplied by (1 or more): the map compares
    /// each frame's ground measurements with the cells' fused heights, and where the
    /// innovations are larger than the stated noise explains (their median normalised square
    /// above a χ²(1) median's 0.455), the noise is larger than the model says and the scale
    /// grows (halfway, in logarithm, each frame). A sensor model that is too optimistic
    /// (a matcher's errors beyond its disparity steps) then neither makes noise look like
    /// roughness nor makes its layers look like steps.
    pub fn noise_scale(&self) -> f64 {
        self.noise_scale
    }

    /// Updates [`GridMap::noise_scale`] from the innovations of the touched cells already seen
    /// whose points this frame all lie on one surface.
    fn rescale(&mut self, touched: &[usize]) {
        let floor = self.cfg.height_floor_m.powi(2);
        let mut q: Vec<f64> = touched
            .iter()
            .filter_map(|&i| {
                let (a, c) = (&self.acc[i], &self.cells[i]);
                // Only cells of one surface, level within the cell: a wall's or a cabinet
                // front's lowest point moves with the viewpoint, which is not noise.
                if c.count == 0 || a.hi.1 > 0 || a.lo.1 < a.n {
                    return None;
                }
                let n = f64::from(a.lo.1);
                let d = a.lo.0 / n - f64::from(c.height_m);
                let s = f64::from(c.var_m2) + self.noise_scale * a.lo.2 / n + floor;
                Some(d * d / (s + 2.0 * f64::from(c.corr_var_m2)))
            })
            .collect();
        if q.len() < MIN_RESCALE_CELLS {
            return;
        }
        let mid = q.len() / 2;
        let median = *q.select_nth_unstable_by(mid, f64::total_cmp).1;
        let step = (median / CHI2_1_MEDIAN).ln() / 2.0;
        if step.is_finite() {
            self.noise_scale = (self.noise_scale * step.exp()).clamp(1.0, MAX_NOISE_SCALE);
        }
    }

    /// Splits each touched cell's points into the low cluster (within the band of the lowest)
    /// and, when the cell's points span more than two bands, the high one.
    fn cluster(&mut self) {
        let (band_m, scale) = (self.cfg.surface_band_m, self.noise_scale);
        for l in &self.landed {
            let a = &mut self.acc[l.slot as usize];
            let var = (scale * a.var_sum + a.corr_sum) / f64::from(a.n);
            let band = band_m.max(3.0 * var.sqrt());
            let (z, var) = (f64::from(l.z), f64::from(l.var));
            if z <= a.z_min + band {
                a.lo = (a.lo.0 + z, a.lo.1 + 1, a.lo.2 + var);
            }
            if a.z_max - a.z_min > 2.0 * band && z >= a.z_max - band {
                a.hi = (a.hi.0 + z, a.hi.1 + 1, a.hi.2 + var);
            }
        }
    }

    /// The window's centre in the map frame, metres.
    pub fn centre(&self) -> (f64, f64) {
        let half = (self.cfg.side / 2) as f64;
        (
            (self.origin.0 as f64 + half) * self.cfg.cell_m,
            (self.origin.1 as f64 + half) * self.cfg.cell_m,
        )
    }

    /// The cell at window position `(col, row)` of the layers' layout
    /// ([`Layers`](super::Layers): column 0 at the window's smallest x, row 0 at its largest y).
    pub fn at(&self, col: usize, row: usize) -> &Cell {
        &self.cells[self.index(col, row)]
    }

    /// Ring-buffer index of window position `(col, row)`.
    fn index(&self, col: usize, row: usize) -> usize {
        let side = self.cfg.side;
        let ix = self.origin.0 + col as i64;
        let iy = self.origin.1 + (side - 1 - row) as i64;
        let s = side as i64;
        (iy.rem_euclid(s) * s + ix.rem_euclid(s)) as usize
    }
}

#[cfg(test)]
mod ring_tests {
    use super::*;

    #[test]
    fn the_ring_finds_the_slot_the_map_does_wherever_the_window_lies() {
        let cfg = MapConfig {
            side: 7,
            cell_m: 0.5,
            ..MapConfig::default()
        };
        let frame = MapFrame {
            map_from_world: Matrix3::identity(),
        };
        for centre in [(0.0, 0.0), (-13.2, 4.9), (101.0, -57.5)] {
            let map = GridMap::new(cfg, frame, centre).unwrap();
            let ring = Ring::of(&map);
            let (ox, oy) = map.origin();
            for ix in ox - 2..ox + 9 {
                for iy in oy - 2..oy + 9 {
                    assert_eq!(ring.slot(ix, iy), map.slot(ix, iy), "{centre:?} {ix},{iy}");
                }
            }
        }
    }
}
