//! Least-squares local planes over pixel windows limited by a metric radius: the LS normals of
//! the geometric baseline and the window centroids of the roughness formula.

use rayon::prelude::*;
use serde::{Deserialize, Serialize};

use super::camera::{is_valid_point, PointMap, INVALID_POINT};
use super::plane::{orient_towards_camera, Moments};
use super::{Grid, Vec3};

/// The neighbourhood of a pixel: the valid points within `radius_m` of it, searched in a pixel
/// window of half-width `clamp(⌈radius_m · fx / z⌉, 1, max_half_width)`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Neighbourhood {
    /// Metric radius R, metres (default 0.05).
    pub radius_m: f64,
    /// Cap on the window half-width, pixels (default 7).
    pub max_half_width: usize,
}

impl Default for Neighbourhood {
    fn default() -> Self {
        Self {
            radius_m: 0.05,
            max_half_width: 7,
        }
    }
}

impl Neighbourhood {
    /// Half-width of the search window for a point at depth `z_m`, seen with focal `fx_px`.
    ///
    /// ```
    /// use tre::geometry::Neighbourhood;
    /// let n = Neighbourhood::default();
    /// assert_eq!(n.half_width(500.0, 5.0), 5);
    /// assert_eq!(n.half_width(500.0, 1.0), 7);
    /// assert_eq!(n.half_width(500.0, 100.0), 1);
    /// ```
    pub fn half_width(&self, fx_px: f64, z_m: f64) -> usize {
        let h = (self.radius_m * fx_px / z_m).ceil();
        if h.is_finite() {
            (h.max(1.0) as usize).min(self.max_half_width.max(1))
        } else {
            self.max_half_width.max(1)
        }
    }

    /// Moments (about `points[(x, y)]`) of the neighbourhood of pixel `(x, y)`.
    pub fn moments(&self, points: &PointMap, fx_px: f64, x: usize, y: usize) -> Moments {
        let p = points[(x, y)];
        if !is_valid_point(&p) {
            return Moments::default();
        }
        let h = self.half_width(fx_px, p.z);
        window_moments(points, x, y, h, self.radius_m * self.radius_m)
    }

    /// The LS normal at `(x, y)` (oriented towards the camera) with the neighbourhood's moments.
    /// Where the neighbourhood is too sparse for a plane (fewer than 3 points within R, or
    /// collinear ones, as at grazing angles), the valid points of the 3×3 window, then the
    /// 5×5 window, stand in without the radius limit.
    pub fn normal(
        &self,
        points: &PointMap,
        fx_px: f64,
        x: usize,
        y: usize,
    ) -> (Moments, Option<Vec3>) {
        let p = points[(x, y)];
        let m = self.moments(points, fx_px, x, y);
        let fit = m.fit(&p).or_else(|| {
            (1..=2).find_map(|h| window_moments(points, x, y, h, f64::INFINITY).fit(&p))
        });
        (m, fit.map(|plane| orient_towards_camera(&plane.normal, &p)))
    }
}

/// Moments about `points[(x, y)]` of the valid points within `sqrt(r2)` of it in the window of
/// half-width `h`.
fn window_moments(points: &PointMap, x: usize, y: usize, h: usize, r2: f64) -> Moments {
    let mut m = Moments::default();
    let p = points[(x, y)];
    {
        let (w, ht) = points.size();
        for yy in y.saturating_sub(h)..(y + h + 1).min(ht) {
            let row = &points.row(yy)[x.saturating_sub(h)..(x + h + 1).min(w)];
            for q in row {
                let d = q - p;
                // NaN (invalid) points fail this comparison.
                if d.norm_squared() <= r2 {
                    m.add(&d);
                }
            }
        }
    }
    m
}

/// Per-pixel local planes: the neighbourhood's mean point and its LS normal.
#[derive(Debug, Clone, PartialEq)]
pub struct LocalPlanes {
    /// Mean of the neighbourhood's points (invalid where the pixel is invalid).
    pub centroid: PointMap,
    /// Unit LS normal oriented towards the camera (NaN where none can be fitted, see
    /// [`Neighbourhood::normal`]).
    pub normal: Grid<Vec3>,
}

/// Fits a local plane at every valid pixel (row-parallel).
pub fn local_planes(points: &PointMap, fx_px: f64, hood: &Neighbourhood) -> LocalPlanes {
    let (w, h) = points.size();
    let mut centroid = Grid::new(w, h, INVALID_POINT);
    let mut normal = Grid::new(w, h, INVALID_POINT);
    centroid
        .as_mut_slice()
        .par_chunks_mut(w.max(1))
        .zip(normal.as_mut_slice().par_chunks_mut(w.max(1)))
        .enumerate()
        .for_each(|(y, (c_row, n_row))| {
            for x in 0..w {
                let (m, normal) = hood.normal(points, fx_px, x, y);
                if let Some(c) = m.mean(&points[(x, y)]) {
                    c_row[x] = c;
                }
                if let Some(n) = normal {
                    n_row[x] = n;
                }
            }
        });
    LocalPlanes { centroid, normal }
}

/// LS normals oriented towards the camera (NaN where none can be fitted).
pub fn ls_normals(points: &PointMap, fx_px: f64, hood: &Neighbourhood) -> Grid<Vec3> {
    local_planes(points, fx_px, hood).normal
}

/// Window centroids only (cheaper than [`local_planes`] when normals come from elsewhere).
pub fn window_centroids(points: &PointMap, fx_px: f64, hood: &Neighbourhood) -> PointMap {
    let (w, h) = points.size();
    let mut centroid = Grid::new(w, h, INVALID_POINT);
    centroid
        .as_mut_slice()
        .par_chunks_mut(w.max(1))
        .enumerate()
        .for_each(|(y, row)| {
            for (x, c) in row.iter_mut().enumerate() {
                if let Some(m) = hood.moments(points, fx_px, x, y).mean(&points[(x, y)]) {
                    *c = m;
                }
            }
        });
    centroid
}
