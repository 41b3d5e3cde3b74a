//! Least-squares local planes over pixel windows limited by a metric radius: the LS normals of
//! the geometric baseline and the window centroids of the roughness formula.

use rayon::prelude::*;
use serde::{Deserialize, Serialize};

use super::camera::{is_valid_point, PointMap, INVALID_POINT};
use super::plane::{orient_towards_camera, smallest_eigenvectors, Moments, EIGEN_LANES};
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

    /// Moments (about `points[(x, y)]`) of the neighbourhood of pixel `(x, y)`: the f64
    /// reference of what the frame kernels compute in f32 lanes.
    pub fn moments(&self, points: &PointMap, fx_px: f64, x: usize, y: usize) -> Moments {
        let p = points[(x, y)];
        if !is_valid_point(&p) {
            return Moments::default();
        }
        let h = self.half_width(fx_px, p.z);
        window_moments(points, x, y, h, self.radius_m * self.radius_m)
    }

    /// Moments of the neighbourhood of `(x, y)` from packed points (windows up to 7 px; wider
    /// ones take the f64 path).
    fn moments_packed(
        &self,
        packed: &PackedPoints,
        points: &PointMap,
        fx_px: f64,
        x: usize,
        y: usize,
    ) -> Moments {
        let p = points[(x, y)];
        if !is_valid_point(&p) {
            return Moments::default();
        }
        match self.half_width(fx_px, p.z) {
            h if h <= 7 => packed.window_moments(x, y, h, self.radius_m),
            h => window_moments(points, x, y, h, self.radius_m * self.radius_m),
        }
    }
}

/// The LS normal at `(x, y)` from the neighbourhood's moments `m`, oriented towards the camera.
/// Where the neighbourhood is too sparse for a plane (fewer than 3 points within R, or collinear
/// ones, as at grazing angles), the valid points of the 3×3, then the 5×5, window stand in
/// without the radius limit.
pub fn normal_from_moments(points: &PointMap, m: &Moments, x: usize, y: usize) -> Option<Vec3> {
    let p = points[(x, y)];
    let fit = m
        .fit(&p)
        .or_else(|| (1..=2).find_map(|h| window_moments(points, x, y, h, f64::INFINITY).fit(&p)));
    fit.map(|plane| orient_towards_camera(&plane.normal, &p))
}

/// Moments about `points[(x, y)]` of the valid points within `sqrt(r2)` of it in the window of
/// half-width `h` (reference implementation, f64).
fn window_moments(points: &PointMap, x: usize, y: usize, h: usize, r2: f64) -> Moments {
    let mut m = Moments::default();
    let p = points[(x, y)];
    let (w, ht) = points.size();
    for yy in y.saturating_sub(h)..(y + h + 1).min(ht) {
        for q in &points.row(yy)[x.saturating_sub(h)..(x + h + 1).min(w)] {
            let d = q - p;
            // NaN (invalid) points fail this comparison.
            if d.norm_squared() <= r2 {
                m.add(&d);
            }
        }
    }
    m
}

/// Lanes per chunk of the vectorised window kernel.
const LANES: usize = 8;
/// Columns of padding (invalid points) on each side of a row of [`PackedPoints`].
const PAD: usize = 8;

/// Points as f32 structure-of-arrays rows padded with invalid (NaN) columns, so that the window
/// kernel reads fixed 8-lane chunks that LLVM vectorises, with no bounds special cases.
#[derive(Debug, Clone, Default)]
pub struct PackedPoints {
    width: usize,
    height: usize,
    stride: usize,
    xyz: [Vec<f32>; 3],
}

impl PackedPoints {
    /// Packs `points` (reusing this buffer's allocations).
    pub fn pack(&mut self, points: &PointMap) {
        let (w, h) = points.size();
        (self.width, self.height, self.stride) = (w, h, w + 2 * PAD);
        for (c, buf) in self.xyz.iter_mut().enumerate() {
            buf.clear();
            buf.resize(self.stride * h, f32::NAN);
            buf.par_chunks_mut(self.stride.max(1))
                .enumerate()
                .for_each(|(y, row)| {
                    for (dst, p) in row[PAD..PAD + w].iter_mut().zip(points.row(y)) {
                        *dst = if is_valid_point(p) {
                            p[c] as f32
                        } else {
                            f32::NAN
                        };
                    }
                });
        }
    }

    /// Moments about point `(x, y)` of the valid points within `radius_m` of it in the window
    /// of half-width `h` (at most 7), accumulated in f32 lanes and returned in f64.
    pub fn window_moments(&self, x: usize, y: usize, h: usize, radius_m: f64) -> Moments {
        let h = h.min(7);
        let centre = self.stride * y + PAD + x;
        let p = [0, 1, 2].map(|c| self.xyz[c][centre]);
        let r2 = (radius_m * radius_m) as f32;
        // Columns x − 3 … x + 4 (one chunk) or x − 7 … x + 8 (two chunks).
        let (first_dx, chunks) = if h <= 3 { (-3isize, 1) } else { (-7isize, 2) };
        let mut acc = [[0f32; LANES]; 10];
        // Per lane of each chunk, the largest squared distance kept: r² inside the window
        // (|dx| ≤ h), −1 (nothing) outside it.
        let limit: [[f32; LANES]; 2] = std::array::from_fn(|c| {
            std::array::from_fn(|l| {
                let inside = (first_dx + (c * LANES + l) as isize).abs() <= h as isize;
                if inside {
                    r2
                } else {
                    -1.0
                }
            })
        });
        for yy in y.saturating_sub(h)..(y + h + 1).min(self.height) {
            let row_start = self.stride * yy + PAD + x;
            for (c, limit) in limit.iter().enumerate().take(chunks) {
                let start = (row_start as isize + first_dx) as usize + c * LANES;
                accumulate_chunk(&mut acc, self.chunk(start), p, limit);
            }
        }
        reduce(&acc)
    }

    fn chunk(&self, start: usize) -> [&[f32; LANES]; 3] {
        let lanes = |c: usize| {
            self.xyz[c][start..]
                .first_chunk::<LANES>()
                .expect("padded rows hold whole chunks; this is a bug")
        };
        [lanes(0), lanes(1), lanes(2)]
    }
}

/// Adds one 8-lane chunk of a window row to the lane accumulators (count, Σd, Σddᵀ).
#[inline(always)]
fn accumulate_chunk(
    acc: &mut [[f32; LANES]; 10],
    q: [&[f32; LANES]; 3],
    p: [f32; 3],
    limit: &[f32; LANES],
) {
    for l in 0..LANES {
        let (dx, dy, dz) = (q[0][l] - p[0], q[1][l] - p[1], q[2][l] - p[2]);
        // NaN (invalid) points fail the comparison; rejected lanes add zeros.
        let keep = mul_add(dz, dz, mul_add(dy, dy, dx * dx)) <= limit[l];
        let mask = if keep { u32::MAX } else { 0 };
        let [dx, dy, dz, one] = [dx, dy, dz, 1.0].map(|v| f32::from_bits(v.to_bits() & mask));
        acc[0][l] += one;
        acc[1][l] += dx;
        acc[2][l] += dy;
        acc[3][l] += dz;
        acc[4][l] = mul_add(dx, dx, acc[4][l]);
        acc[5][l] = mul_add(dx, dy, acc[5][l]);
        acc[6][l] = mul_add(dx, dz, acc[6][l]);
        acc[7][l] = mul_add(dy, dy, acc[7][l]);
        acc[8][l] = mul_add(dy, dz, acc[8][l]);
        acc[9][l] = mul_add(dz, dz, acc[9][l]);
    }
}

/// `a·b + c`: one fused multiply-add where the build targets FMA (x86-64-v3, the default here),
/// else a multiply and an add (a software `fma` call would be far slower).
#[inline(always)]
fn mul_add(a: f32, b: f32, c: f32) -> f32 {
    if cfg!(target_feature = "fma") {
        a.mul_add(b, c)
    } else {
        a * b + c
    }
}

fn reduce(acc: &[[f32; LANES]; 10]) -> Moments {
    let sum = |i: usize| acc[i].iter().map(|&v| f64::from(v)).sum::<f64>();
    Moments {
        count: sum(0) as u32,
        sum: Vec3::new(sum(1), sum(2), sum(3)),
        sum_sq: [sum(4), sum(5), sum(6), sum(7), sum(8), sum(9)],
    }
}

/// Per-pixel local planes: the neighbourhood's mean point and its LS normal.
#[derive(Debug, Clone, PartialEq)]
pub struct LocalPlanes {
    /// Mean of the neighbourhood's points (invalid where the pixel is invalid).
    pub centroid: PointMap,
    /// Unit LS normal oriented towards the camera (NaN where none can be fitted, see
    /// [`normal_from_moments`]).
    pub normal: Grid<Vec3>,
}

/// Fits a local plane at every valid pixel (row-parallel; the eigen-solves of a row run four
/// pixels at a time).
pub fn local_planes(points: &PointMap, fx_px: f64, hood: &Neighbourhood) -> LocalPlanes {
    let (w, h) = points.size();
    let mut packed = PackedPoints::default();
    packed.pack(points);
    let mut centroid = Grid::new(w, h, INVALID_POINT);
    let mut normal = Grid::new(w, h, INVALID_POINT);
    centroid
        .par_rows_mut()
        .zip(normal.par_rows_mut())
        .for_each(|((y, c_row), (_, n_row))| {
            for x0 in (0..w).step_by(EIGEN_LANES) {
                let m: [Moments; EIGEN_LANES] = std::array::from_fn(|l| {
                    let x = x0 + l;
                    if x < w {
                        hood.moments_packed(&packed, points, fx_px, x, y)
                    } else {
                        Moments::default()
                    }
                });
                let fits = smallest_eigenvectors(&m.map(|m| m.covariance()));
                for l in 0..EIGEN_LANES.min(w - x0) {
                    let (x, p) = (x0 + l, points[(x0 + l, y)]);
                    let Some(c) = m[l].mean(&p) else { continue };
                    c_row[x] = c;
                    let n = match fits[l] {
                        Some(n) if m[l].count >= 3 => Some(orient_towards_camera(&n, &p)),
                        _ => normal_from_moments(points, &m[l], x, y),
                    };
                    n_row[x] = n.unwrap_or(INVALID_POINT);
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
    let mut packed = PackedPoints::default();
    packed.pack(points);
    let mut centroid = Grid::new(w, h, INVALID_POINT);
    centroid.par_rows_mut().for_each(|(y, row)| {
        for (x, c) in row.iter_mut().enumerate() {
            if let Some(m) = hood
                .moments_packed(&packed, points, fx_px, x, y)
                .mean(&points[(x, y)])
            {
                *c = m;
            }
        }
    });
    centroid
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn packed_kernel_matches_the_f64_reference() {
        // A bumpy surface with holes, every half-width from 1 to 7.
        let (w, h) = (40, 30);
        let pts = Grid::from_fn(w, h, |x, y| {
            if (x * 7 + y * 3) % 11 == 0 {
                INVALID_POINT
            } else {
                let (u, v) = (x as f64 * 0.01, y as f64 * 0.012);
                Vec3::new(u, v, 2.0 + 0.02 * (u * 40.0).sin() + 0.3 * v)
            }
        });
        let mut packed = PackedPoints::default();
        packed.pack(&pts);
        for half in 1..=7 {
            for (x, y) in [(0, 0), (5, 5), (20, 15), (39, 29), (38, 1), (7, 28)] {
                if !is_valid_point(&pts[(x, y)]) {
                    continue;
                }
                let a = packed.window_moments(x, y, half, 0.05);
                let b = window_moments(&pts, x, y, half, 0.05 * 0.05);
                assert_eq!(a.count, b.count, "({x}, {y}) h {half}");
                // f32 coordinates carry ~1e-7 m of rounding; means agree to well under 1e-6 m.
                let n = f64::from(a.count);
                assert!((a.sum - b.sum).norm() / n < 5e-7, "({x}, {y}) h {half}");
                for (p, q) in a.sum_sq.iter().zip(b.sum_sq) {
                    assert!((p - q).abs() / n < 1e-8);
                }
            }
        }
    }
}
