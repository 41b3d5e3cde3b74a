//! The robot's map: a gravity-aligned grid of cells fused over frames (docs/map.md).
//!
//! The map frame is the world frame of the poses turned so that its z axis is gravity's up
//! ([`MapFrame`]); cells are `cell_m` squares of that frame's x–y plane. The grid covers a
//! square of `side` cells around a centre that follows the robot: storage is a ring buffer
//! indexed by world cell modulo the side, so recentring clears only the rows and columns that
//! leave the window ([`GridMap::recentre`]) and never copies the grid.
//!
//! Each cell keeps a height estimate fused by a scalar Kalman filter ([`Cell::fuse_height`]):
//! per frame, the points that fall in the cell give one measurement (their mean height) whose
//! variance is the depth sensor's σ_z² at their depth (the noise is correlated across a
//! cell's neighbouring pixels, so the count does not shrink it). A measurement more than
//! three standard deviations of the innovation from the estimate is an outlier: it is not
//! fused and is counted; three outliers in a row mean the cell changed (an object moved in or
//! out), and the cell restarts from the new measurement. Roughness is the mean of the frames'
//! per-pixel roughness in the cell weighted by 1/σ_z² (near pixels, whose roughness carries
//! less sensor noise, count most); slope and step height come from the heights of
//! neighbouring cells when the map is read ([`GridMap::layers`]).

mod layers;

pub use layers::{Layers, MapLimits, LAYER_NAMES, LAYER_UNITS};

use nalgebra::{Matrix3, Matrix4, Vector3};

use crate::geometry::floor::{fit_floor, FloorFitConfig};
use crate::geometry::{is_valid_point, Grid, PointMap, Vec3};

/// How a map is laid out.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MapConfig {
    /// Side of a cell, metres (default 0.04).
    pub cell_m: f64,
    /// Cells along each side of the square window (default 200: 8 m at 4 cm).
    pub side: usize,
    /// Process noise of a cell's height, m² per second (the world changes slowly).
    pub process_var_per_s: f64,
    /// Innovations beyond this many standard deviations are outliers (default 3).
    pub outlier_sigmas: f64,
    /// Outliers in a row after which a cell restarts from the new measurement (default 3).
    pub restart_after: u32,
    /// Points beyond this distance from the camera are left out, metres (default 4).
    pub max_range_m: f64,
}

impl Default for MapConfig {
    fn default() -> Self {
        Self {
            cell_m: 0.04,
            side: 200,
            process_var_per_s: 1e-6,
            outlier_sigmas: 3.0,
            restart_after: 3,
            max_range_m: 4.0,
        }
    }
}

impl MapConfig {
    /// A square window `size_m` across in cells of `cell_m` (the cell count rounded), points
    /// kept within `max_range_m`, the rest as the default (`tre map --cell-cm --size-m
    /// --max-range-m`).
    ///
    /// ```
    /// let cfg = tre_core::map::MapConfig::square(0.04, 8.0, 3.0);
    /// assert_eq!((cfg.side, cfg.max_range_m), (200, 3.0));
    /// ```
    #[must_use]
    pub fn square(cell_m: f64, size_m: f64, max_range_m: f64) -> Self {
        Self {
            cell_m,
            side: (size_m / cell_m).round() as usize,
            max_range_m,
            ..Self::default()
        }
    }
}

/// Why a frame was not fused; the map keeps what it had.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum MapError {
    /// A pose whose rotation is not a rotation (or not finite).
    #[error(
        "the pose is not a rigid transform (rotation off by {error:.2e}: RᵀR must be I, det R = 1, \
         the last row 0 0 0 1)"
    )]
    NotRigid {
        /// Largest deviation found.
        error: f64,
    },
    /// The camera is farther from the map's centre than the map can follow in one step.
    #[error(
        "the camera is {distance_m:.1} m from the map's centre, beyond {limit_m:.1} m: a pose in \
         another frame or a jump; skipped"
    )]
    TooFar {
        /// The distance, metres.
        distance_m: f64,
        /// The largest accepted, metres.
        limit_m: f64,
    },
    /// No point of the frame fell in the map.
    #[error("the frame has no valid point within range of the map; skipped")]
    NothingSeen,
    /// A gravity direction of zero length (or not finite).
    #[error("map configuration: gravity {0:?} has no direction")]
    NoGravityDirection([f64; 3]),
    /// A cell size that is not positive, or a side outside 1 to 8192 cells.
    #[error(
        "map configuration: cell {cell_m} m and side {side} cells: the cell must be positive and \
         the side 1 to 8192"
    )]
    BadGrid {
        /// Cell side, metres.
        cell_m: f64,
        /// Cells per side.
        side: usize,
    },
    /// No gravity was given or stated and the first frame shows no ground to level by.
    #[error("no gravity given, no pitch stated, and no ground in the first frame")]
    NoGround,
    /// No gravity was given or stated and the first frame's ground fit is not confident.
    #[error(
        "no gravity given, no pitch stated, and the first frame's ground fit is not confident \
         ({:.1}% of the points on it): the map cannot be levelled", 100.0 * support
    )]
    GroundNotConfident {
        /// Share of the valid points on the fitted plane.
        support: f64,
    },
}

/// The map frame: the world frame of the poses turned so that z is gravity's up.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MapFrame {
    /// Rotation from the world frame to the map frame.
    pub map_from_world: Matrix3<f64>,
}

impl MapFrame {
    /// The map frame of a world whose gravity (pointing down) is `down`: the rotation taking
    /// `-down` to +z by the shortest turn.
    ///
    /// ```
    /// use tre_core::map::MapFrame;
    /// let f = MapFrame::from_gravity(&nalgebra::Vector3::new(0.0, 1.0, 0.0)).unwrap();
    /// let up = f.map_from_world * nalgebra::Vector3::new(0.0, -1.0, 0.0);
    /// assert!((up - nalgebra::Vector3::z()).norm() < 1e-12);
    /// ```
    pub fn from_gravity(down: &Vec3) -> Result<Self, MapError> {
        let up = -down
            .try_normalize(1e-9)
            .ok_or(MapError::NoGravityDirection([down.x, down.y, down.z]))?;
        let rot = nalgebra::Rotation3::rotation_between(&up, &Vector3::z()).unwrap_or_else(|| {
            nalgebra::Rotation3::from_axis_angle(&Vector3::x_axis(), std::f64::consts::PI)
        });
        Ok(Self {
            map_from_world: *rot.matrix(),
        })
    }
}

impl MapFrame {
    /// The map frame of a sequence, from the first of: the world's gravity `down` (a
    /// sequence's `gravity.json`), the camera's stated up direction `up_in_cam` (its mounting)
    /// turned into the world by the first frame's `pose`, the ground plane fitted on the first
    /// frame's `points` (only when the fit is confident).
    pub fn levelled(
        down: Option<Vec3>,
        up_in_cam: Option<Vec3>,
        points: &PointMap,
        pose: &Pose,
    ) -> Result<Self, MapError> {
        if let Some(down) = down {
            return Self::from_gravity(&down);
        }
        let up_cam = match up_in_cam {
            Some(up) => up,
            None => {
                let fit = fit_floor(points, &FloorFitConfig::default())
                    .map_err(|_| MapError::NoGround)?;
                if !fit.confident {
                    return Err(MapError::GroundNotConfident {
                        support: fit.support,
                    });
                }
                fit.up_in_cam
            }
        };
        Self::from_gravity(&-(pose.rotation * up_cam))
    }
}

/// A camera-to-world pose checked to be rigid.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Pose {
    /// Rotation, camera to world.
    pub rotation: Matrix3<f64>,
    /// The camera's centre in the world, metres.
    pub translation: Vec3,
}

impl Pose {
    /// The pose of a 4×4 camera-to-world matrix, if it is rigid (within 1e-3).
    ///
    /// ```
    /// use tre_core::map::Pose;
    /// assert!(Pose::from_matrix(&nalgebra::Matrix4::identity()).is_ok());
    /// let mut m = nalgebra::Matrix4::identity();
    /// m[(0, 0)] = 2.0;
    /// assert!(Pose::from_matrix(&m).is_err());
    /// ```
    pub fn from_matrix(m: &Matrix4<f64>) -> Result<Self, MapError> {
        let r: Matrix3<f64> = m.fixed_view::<3, 3>(0, 0).into_owned();
        let orth = (r.transpose() * r - Matrix3::identity()).abs().max();
        let det = (r.determinant() - 1.0).abs();
        let last = (m[(3, 0)].abs() + m[(3, 1)].abs() + m[(3, 2)].abs() + (m[(3, 3)] - 1.0).abs())
            .max(0.0);
        let error = orth.max(det).max(last);
        if !(error <= 1e-3) || m.iter().any(|v| !v.is_finite()) {
            return Err(MapError::NotRigid {
                error: if error.is_finite() {
                    error
                } else {
                    f64::INFINITY
                },
            });
        }
        Ok(Self {
            rotation: r,
            translation: Vector3::new(m[(0, 3)], m[(1, 3)], m[(2, 3)]),
        })
    }

    /// The pose of 16 numbers, a 4×4 camera-to-world matrix row by row, if it is rigid.
    pub fn from_row_major(v: &[f64]) -> Result<Self, MapError> {
        if v.len() != 16 {
            return Err(MapError::NotRigid {
                error: f64::INFINITY,
            });
        }
        Self::from_matrix(&Matrix4::from_row_slice(v))
    }

    /// The identity: the camera is the world (a robot-centred map of one frame).
    pub fn identity() -> Self {
        Self {
            rotation: Matrix3::identity(),
            translation: Vec3::zeros(),
        }
    }
}

/// One cell's state.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Cell {
    /// Height estimate in the map frame, metres (NaN: never seen).
    pub height_m: f32,
    /// Its variance, m².
    pub var_m2: f32,
    /// Measurements fused.
    pub count: u32,
    /// Outliers in a row.
    pub outliers: u32,
    /// Time of the last fused measurement, seconds.
    pub last_s: f64,
    /// Count-weighted mean roughness, metres.
    pub roughness_m: f32,
    /// Weight behind the roughness mean (Σ 1/σ_z² of its pixels, m⁻²).
    pub roughness_w: f32,
}

impl Default for Cell {
    fn default() -> Self {
        Self {
            height_m: f32::NAN,
            var_m2: f32::INFINITY,
            count: 0,
            outliers: 0,
            last_s: f64::NAN,
            roughness_m: f32::NAN,
            roughness_w: 0.0,
        }
    }
}

/// What one measurement did to a cell.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Fused {
    /// The first measurement, or a restart after [`MapConfig::restart_after`] outliers.
    Started,
    /// A Kalman update.
    Updated,
    /// Rejected as an outlier.
    Outlier,
}

impl Cell {
    /// Fuses a height measurement `z_m` of variance `r_m2` taken at `t_s` into the cell:
    /// prediction `P += q·Δt`, innovation `d = z − h`, `S = P + R`; an outlier when
    /// `d² > k²·S`; else `K = P / S`, `h += K·d`, `P = (1 − K)·P`.
    ///
    /// ```
    /// use tre_core::map::{Cell, Fused, MapConfig};
    /// let cfg = MapConfig { process_var_per_s: 0.0, ..MapConfig::default() };
    /// let mut c = Cell::default();
    /// assert_eq!(c.fuse_height(1.0, 0.04, 0.0, &cfg), Fused::Started);
    /// // P = 0.04, R = 0.04: K = 0.5, h = 1.0 + 0.5·0.2 = 1.1, P = 0.02.
    /// assert_eq!(c.fuse_height(1.2, 0.04, 1.0, &cfg), Fused::Updated);
    /// assert!((c.height_m - 1.1).abs() < 1e-6 && (c.var_m2 - 0.02).abs() < 1e-8);
    /// ```
    pub fn fuse_height(&mut self, z_m: f64, r_m2: f64, t_s: f64, cfg: &MapConfig) -> Fused {
        if self.count == 0 || !self.height_m.is_finite() {
            self.start(z_m, r_m2, t_s);
            return Fused::Started;
        }
        let dt = if t_s.is_finite() && self.last_s.is_finite() {
            (t_s - self.last_s).max(0.0)
        } else {
            0.0
        };
        let p = f64::from(self.var_m2) + cfg.process_var_per_s * dt;
        let d = z_m - f64::from(self.height_m);
        let s = p + r_m2;
        if d * d > cfg.outlier_sigmas * cfg.outlier_sigmas * s {
            self.outliers += 1;
            if self.outliers >= cfg.restart_after {
                self.start(z_m, r_m2, t_s);
                return Fused::Started;
            }
            return Fused::Outlier;
        }
        let k = p / s;
        self.height_m = (f64::from(self.height_m) + k * d) as f32;
        self.var_m2 = ((1.0 - k) * p) as f32;
        self.count += 1;
        self.outliers = 0;
        self.last_s = t_s;
        Fused::Updated
    }

    fn start(&mut self, z_m: f64, r_m2: f64, t_s: f64) {
        self.height_m = z_m as f32;
        self.var_m2 = r_m2 as f32;
        self.count = 1;
        self.outliers = 0;
        self.last_s = t_s;
        self.roughness_m = f32::NAN;
        self.roughness_w = 0.0;
    }

    /// Adds roughness `mean_m` of weight `w` (Σ 1/σ_z² of its pixels) to the cell's weighted
    /// mean: near pixels, whose roughness noise is small, count most.
    fn add_roughness(&mut self, mean_m: f64, w: f64) {
        if !(mean_m.is_finite() && w > 0.0) {
            return;
        }
        let old = f64::from(self.roughness_w);
        let prev = if old > 0.0 {
            f64::from(self.roughness_m)
        } else {
            0.0
        };
        self.roughness_m = ((prev * old + mean_m * w) / (old + w)) as f32;
        self.roughness_w = (old + w) as f32;
    }
}

/// What a frame did to the map.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct FuseStats {
    /// Points that fell in the map.
    pub points: usize,
    /// Cells measured.
    pub cells: usize,
    /// Cells started (first seen or restarted).
    pub started: usize,
    /// Cells whose measurement was an outlier.
    pub outliers: usize,
}

/// A gravity-aligned grid map fused over frames.
#[derive(Debug, Clone)]
pub struct GridMap {
    cfg: MapConfig,
    frame: MapFrame,
    /// World cell index of the window's lower-left cell.
    origin: (i64, i64),
    /// Ring buffer, `side × side`, cell (ix, iy) at `(ix mod side, iy mod side)`.
    cells: Vec<Cell>,
    /// Per-frame accumulators (reused): height sum, height count, roughness sum and count, depth
    /// sum.
    acc: Vec<Acc>,
}

#[derive(Debug, Clone, Copy, Default)]
struct Acc {
    z_sum: f64,
    n: u32,
    r_sum: f64,
    r_w: f64,
    depth_sum: f64,
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

    /// Memory the map holds, bytes: cells and the frame accumulator, fixed by its side.
    pub fn memory_bytes(&self) -> usize {
        self.cells.len() * (std::mem::size_of::<Cell>() + std::mem::size_of::<Acc>())
    }

    fn origin_for(&self, (x, y): (f64, f64)) -> (i64, i64) {
        let half = (self.cfg.side / 2) as i64;
        (self.cell_of(x) - half, self.cell_of(y) - half)
    }

    fn cell_of(&self, v: f64) -> i64 {
        (v / self.cfg.cell_m).floor() as i64
    }

    /// Ring-buffer slot of world cell `(ix, iy)`, if it is in the window.
    fn slot(&self, ix: i64, iy: i64) -> Option<usize> {
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

    /// Fuses one frame: `points` in the camera frame (a back-projected depth map), their
    /// roughness (same size; NaN: none), the camera's `pose`, the time `t_s`, and `sigma_z`
    /// (the depth sensor's σ_z in metres at a depth). The window follows the camera (recentred
    /// when it is more than a quarter of the side from the centre).
    ///
    /// # Errors
    ///
    /// [`MapError::TooFar`] for a camera more than the window's side from its centre, and
    /// [`MapError::NothingSeen`] when no point lands in the map; the map is unchanged.
    pub fn fuse(
        &mut self,
        points: &PointMap,
        roughness_m: Option<&Grid<f64>>,
        pose: &Pose,
        t_s: f64,
        sigma_z: impl Fn(f64) -> f64,
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
        let (touched, points_in) = self.accumulate(points, roughness_m, (&rot, &cam), &sigma_z);
        if touched.is_empty() {
            return Err(MapError::NothingSeen);
        }
        let mut stats = FuseStats {
            points: points_in,
            ..FuseStats::default()
        };
        for i in touched {
            let a = std::mem::take(&mut self.acc[i]);
            let n = f64::from(a.n);
            let (z, depth) = (a.z_sum / n, a.depth_sum / n);
            let r = sigma_z(depth).powi(2) + self.cfg.cell_m.powi(2) / 12.0;
            let cell = &mut self.cells[i];
            stats.cells += 1;
            match cell.fuse_height(z, r, t_s, &self.cfg) {
                Fused::Started => stats.started += 1,
                Fused::Updated => {}
                Fused::Outlier => {
                    stats.outliers += 1;
                    continue;
                }
            }
            if a.r_w > 0.0 {
                cell.add_roughness(a.r_sum / a.r_w, a.r_w);
            }
        }
        Ok(stats)
    }

    /// Adds the frame's points (camera frame, turned by `rot` and moved by `trans` into the
    /// map frame) to the accumulators of their cells; returns the cells touched and the points
    /// that landed in the window.
    fn accumulate(
        &mut self,
        points: &PointMap,
        roughness_m: Option<&Grid<f64>>,
        (rot, trans): (&Matrix3<f64>, &Vec3),
        sigma_z: &impl Fn(f64) -> f64,
    ) -> (Vec<usize>, usize) {
        let mut touched: Vec<usize> = Vec::new();
        let mut landed = 0;
        let (w, h) = points.size();
        for y in 0..h {
            for x in 0..w {
                let p = points[(x, y)];
                if !is_valid_point(&p) || p.z > self.cfg.max_range_m {
                    continue;
                }
                let m = rot * p + trans;
                let Some(i) = self.slot(self.cell_of(m.x), self.cell_of(m.y)) else {
                    continue;
                };
                let a = &mut self.acc[i];
                if a.n == 0 {
                    touched.push(i);
                }
                a.z_sum += m.z;
                a.n += 1;
                a.depth_sum += p.z;
                if let Some(r) = roughness_m.map(|r| r[(x, y)]).filter(|r| r.is_finite()) {
                    let w = 1.0 / sigma_z(p.z).powi(2).max(1e-8);
                    a.r_sum += w * r;
                    a.r_w += w;
                }
                landed += 1;
            }
        }
        (touched, landed)
    }

    /// The window's centre in the map frame, metres.
    pub fn centre(&self) -> (f64, f64) {
        let half = (self.cfg.side / 2) as f64;
        (
            (self.origin.0 as f64 + half) * self.cfg.cell_m,
            (self.origin.1 as f64 + half) * self.cfg.cell_m,
        )
    }

    /// The cell at window position `(col, row)` of the layers' layout ([`Layers`]: column 0 at
    /// the window's smallest x, row 0 at its largest y).
    pub fn at(&self, col: usize, row: usize) -> &Cell {
        let side = self.cfg.side;
        let ix = self.origin.0 + col as i64;
        let iy = self.origin.1 + (side - 1 - row) as i64;
        let s = side as i64;
        &self.cells[(iy.rem_euclid(s) * s + ix.rem_euclid(s)) as usize]
    }
}

#[cfg(test)]
mod tests;
