//! One cell of the map: the ground (the lowest surface seen, a scalar Kalman filter of its
//! height) and the highest surface seen above it, kept apart so that a counter top or an
//! overhang does not pull the floor up (docs/map.md).

use super::MapConfig;

/// One cell's state.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Cell {
    /// Height of the ground (the lowest surface seen) in the map frame, metres (NaN: never seen).
    pub height_m: f32,
    /// Its variance, m².
    pub var_m2: f32,
    /// Measurements fused into the ground.
    pub count: u32,
    /// Measurements below the ground beyond the outlier bound, in a row.
    pub outliers: u32,
    /// Time of the last fused ground measurement, seconds.
    pub last_s: f64,
    /// Height of the highest surface seen above the ground, metres (NaN: none).
    pub upper_m: f32,
    /// Its variance, m².
    pub upper_var_m2: f32,
    /// Measurements fused into the upper surface.
    pub upper_count: u32,
    /// The correlated part of the height's variance, m²: an error its measurements share
    /// (accumulated LiDAR's registration offsets), which fusing them does not reduce. The
    /// height's whole variance is `var_m2 + corr_var_m2`.
    pub corr_var_m2: f32,
}

impl Default for Cell {
    fn default() -> Self {
        Self {
            height_m: f32::NAN,
            var_m2: f32::INFINITY,
            count: 0,
            outliers: 0,
            last_s: f64::NAN,
            upper_m: f32::NAN,
            upper_var_m2: f32::INFINITY,
            upper_count: 0,
            corr_var_m2: 0.0,
        }
    }
}

/// What one ground measurement did to a cell.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Fused {
    /// The first measurement, or a restart after [`MapConfig::restart_after`] measurements in
    /// a row below the ground (what was taken for the ground was a surface above it).
    Started,
    /// A Kalman update.
    Updated,
    /// Beyond the outlier bound, below the ground or within the band above it: not fused,
    /// counted.
    Outlier,
    /// Above the ground beyond the outlier bound and the surface band: a surface over the
    /// ground (a counter top, an overhang, something that moved in), fused into the upper
    /// surface instead.
    Above,
}

/// One scalar Kalman step: prediction `P += q·Δt`, innovation `d = z − h`, `S = P + R`; `None`
/// (an outlier) when `d² > k²·(S + 2·C)` (`C` the correlated variance the estimate and the
/// measurement each carry), else `(h + K·d, (1 − K)·P)` with `K = P / S`, and the sign of `d`
/// either way.
fn kalman(
    (h, p, corr): (f64, f64, f64),
    (z, r): (f64, f64),
    dt: f64,
    cfg: &MapConfig,
) -> (Option<(f64, f64)>, f64) {
    let p = p + cfg.process_var_per_s * dt;
    let d = z - h;
    let s = p + r;
    if d * d > cfg.outlier_sigmas * cfg.outlier_sigmas * (s + 2.0 * corr) {
        return (None, d);
    }
    let k = p / s;
    (Some((h + k * d, (1.0 - k) * p)), d)
}

impl Cell {
    /// Fuses a ground measurement `z_m` of variance `r_m2` taken at `t_s` into the cell
    /// (a scalar Kalman step). A measurement beyond the bound and more than
    /// [`MapConfig::surface_band_m`] above the ground is a surface over it and goes to
    /// [`Cell::fuse_upper`]; any other beyond the bound counts as an outlier, and
    /// [`MapConfig::restart_after`] of them in a row restart the ground from the new
    /// measurement (from below, the old ground becomes the upper surface).
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
        let dt = elapsed(self.last_s, t_s);
        let corr = f64::from(self.corr_var_m2);
        let state = (f64::from(self.height_m), f64::from(self.var_m2), corr);
        match kalman(state, (z_m, r_m2), dt, cfg) {
            (Some((h, p)), _) => {
                self.height_m = h as f32;
                self.var_m2 = p as f32;
                self.count += 1;
                self.outliers = 0;
                self.last_s = t_s;
                Fused::Updated
            }
            (None, d) if d > cfg.surface_band_m => {
                self.fuse_upper(z_m, r_m2, cfg);
                Fused::Above
            }
            (None, d) => {
                self.outliers += 1;
                if self.outliers < cfg.restart_after {
                    return Fused::Outlier;
                }
                let (old, old_var) = (self.height_m, self.var_m2);
                let upper = (self.upper_m, self.upper_var_m2, self.upper_count);
                self.start(z_m, r_m2, t_s);
                // Below: the old ground was a surface above the new one, and the higher of it
                // and the upper surface stays as the upper surface. Within the band above: the
                // ground was misread, and only it restarts.
                if d < -cfg.surface_band_m && !(upper.0 >= old) {
                    (self.upper_m, self.upper_var_m2, self.upper_count) = (old, old_var, 1);
                } else {
                    (self.upper_m, self.upper_var_m2, self.upper_count) = upper;
                }
                Fused::Started
            }
        }
    }

    /// Fuses a measurement `z_m` of a surface above the ground into the upper surface: a
    /// Kalman step, or a restart when it is not that surface (something else is now the
    /// highest). Measurements within the outlier bound or the surface band of the ground are
    /// not an upper surface and are left out.
    pub fn fuse_upper(&mut self, z_m: f64, r_m2: f64, cfg: &MapConfig) {
        let corr = f64::from(self.corr_var_m2);
        if self.count > 0 {
            let s = f64::from(self.var_m2) + r_m2 + 2.0 * corr;
            let d = z_m - f64::from(self.height_m);
            if !(d > cfg.surface_band_m && d * d > cfg.outlier_sigmas * cfg.outlier_sigmas * s) {
                return;
            }
        }
        if self.upper_count == 0 || !self.upper_m.is_finite() {
            (self.upper_m, self.upper_var_m2, self.upper_count) = (z_m as f32, r_m2 as f32, 1);
            return;
        }
        let state = (f64::from(self.upper_m), f64::from(self.upper_var_m2), corr);
        match kalman(state, (z_m, r_m2), 0.0, cfg) {
            (Some((h, p)), _) => {
                (self.upper_m, self.upper_var_m2) = (h as f32, p as f32);
                self.upper_count += 1;
            }
            (None, _) => {
                (self.upper_m, self.upper_var_m2, self.upper_count) = (z_m as f32, r_m2 as f32, 1);
            }
        }
    }

    fn start(&mut self, z_m: f64, r_m2: f64, t_s: f64) {
        self.height_m = z_m as f32;
        self.var_m2 = r_m2 as f32;
        self.count = 1;
        self.outliers = 0;
        self.last_s = t_s;
        if self.upper_m <= self.height_m {
            (self.upper_m, self.upper_var_m2, self.upper_count) = (f32::NAN, f32::INFINITY, 0);
        }
    }

    /// Adds a measurement's correlated variance `c_m2` to the cell's (their mean over the
    /// measurements: an error they share does not average out).
    pub fn add_correlated(&mut self, c_m2: f64) {
        let n = f64::from(self.count.max(1));
        let mean = f64::from(self.corr_var_m2);
        self.corr_var_m2 = (mean + (c_m2 - mean) / n) as f32;
    }

    /// The height's whole variance: the fused (white) part and the correlated part, m².
    pub fn total_var_m2(&self) -> f32 {
        self.var_m2 + self.corr_var_m2
    }

    /// The clearance between the ground and the upper surface, metres (NaN: no upper surface).
    pub fn clearance_m(&self) -> f32 {
        if self.upper_count > 0 {
            self.upper_m - self.height_m
        } else {
            f32::NAN
        }
    }
}

/// Seconds from `last_s` to `t_s` (0 when either is unknown or time went back).
fn elapsed(last_s: f64, t_s: f64) -> f64 {
    if t_s.is_finite() && last_s.is_finite() {
        (t_s - last_s).max(0.0)
    } else {
        0.0
    }
}
