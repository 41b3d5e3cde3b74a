//! Least-squares local planes over pixel windows limited by a metric radius: the LS normals of
//! the geometric baseline and the window centroids of the roughness formula.

use multiversion::multiversion;
use rayon::prelude::*;
use serde::{Deserialize, Serialize};

use super::camera::{is_valid_point, PointMap, INVALID_POINT};
use super::plane::{fit_normals, orient_towards_camera, Moments};
use super::simd::from_fn;
use super::{Grid, Vec3};

/// The neighbourhood of a pixel: the valid points within `radius_m` of it, searched in a pixel
/// window of half-width `clamp(⌈radius_m · fx / z⌉, 1, max_half_width)`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[cfg_attr(feature = "cli", derive(clap::Args))]
pub struct Neighbourhood {
    /// Neighbourhood radius R, metres.
    #[cfg_attr(feature = "cli", arg(long, default_value_t = 0.05))]
    pub radius_m: f64,
    /// Cap on the window half-width, pixels.
    #[cfg_attr(feature = "cli", arg(long, default_value_t = 7))]
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
    /// use tre_core::geometry::normals::Neighbourhood;
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

    /// Moments of the neighbourhoods of the pixels `(x0 + l, y)`, `l < GROUP`, from packed
    /// points (empty for invalid pixels and past the row's end; windows wider than 7 px take
    /// the f64 path).
    #[inline(always)]
    fn group_moments(
        &self,
        packed: &PackedPoints,
        points: &PointMap,
        fx_px: f64,
        x0: usize,
        y: usize,
    ) -> [Moments; GROUP] {
        let mut half = [0; GROUP];
        for (l, h) in half.iter_mut().enumerate() {
            if let Some(p) = points.row(y).get(x0 + l).filter(|p| is_valid_point(p)) {
                *h = self.half_width(fx_px, p.z);
            }
        }
        let packed_half = half.map(|h| if h <= MAX_PACKED_HALF { h } else { 0 });
        let acc = packed.group_moments(x0, y, &packed_half, self.radius_m);
        // A loop, not `from_fn`: the wide windows' f64 path must inline into each compiled
        // version of the row kernel ([`super::simd::from_fn`] says why).
        let mut out = [Moments::default(); GROUP];
        for (l, (m, h)) in out.iter_mut().zip(half).enumerate() {
            *m = match h {
                0 => Moments::default(),
                h if h <= MAX_PACKED_HALF => lane_moments(&acc, l),
                h => window_moments(points, x0 + l, y, h, self.radius_m * self.radius_m),
            };
        }
        out
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
/// half-width `h` (reference implementation, f64; the path of windows wider than the packed
/// kernel's, inlined into each compiled version of the row kernel).
#[inline(always)]
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

/// Pixels per group of the window kernel: one lane per pixel.
pub const GROUP: usize = 8;
/// Columns of invalid padding left of each packed row: a window reaches 7 columns left.
pub(super) const PAD_LEFT: usize = 8;
/// Columns of invalid padding right of each packed row: a group's last pixel (7 columns after
/// its first) plus the 7 columns its window reaches, rounded up.
const PAD_RIGHT: usize = 16;
/// Widest half-width the packed kernel handles; wider windows take the f64 path.
pub(super) const MAX_PACKED_HALF: usize = 7;

/// Points as f32 structure-of-arrays rows padded with invalid (NaN) columns, so that the window
/// kernels (these moments, and the neighbour counts of `neighbours.rs`) read fixed 8-lane
/// chunks that LLVM vectorises, with no bounds special cases.
#[derive(Debug, Clone, Default)]
pub struct PackedPoints {
    pub(super) width: usize,
    pub(super) height: usize,
    pub(super) stride: usize,
    pub(super) xyz: [Vec<f32>; 3],
}

/// The moments of [`GROUP`] neighbourhoods in f32 lanes, one pixel per lane: count, Σd (x, y,
/// z), then Σddᵀ (xx, xy, xz, yy, yz, zz).
pub type GroupMoments = [[f32; GROUP]; 10];

impl PackedPoints {
    /// Packs `points` (reusing this buffer's allocations).
    pub fn pack(&mut self, points: &PointMap) {
        let (w, h) = points.size();
        (self.width, self.height, self.stride) = (w, h, PAD_LEFT + w + PAD_RIGHT);
        for (c, buf) in self.xyz.iter_mut().enumerate() {
            buf.clear();
            buf.resize(self.stride * h, f32::NAN);
            buf.par_chunks_mut(self.stride.max(1))
                .enumerate()
                .for_each(|(y, row)| {
                    for (dst, p) in row[PAD_LEFT..PAD_LEFT + w].iter_mut().zip(points.row(y)) {
                        *dst = if is_valid_point(p) {
                            p[c] as f32
                        } else {
                            f32::NAN
                        };
                    }
                });
        }
    }

    /// Moments of the neighbourhoods of the pixels `(x0 + l, y)` for the lanes `l` of a group:
    /// about each pixel's point, the valid points within `radius_m` of it in its window of
    /// half-width `half[l]` (at most 7; 0 for a lane that needs nothing). Lanes past the row's
    /// end and invalid pixels get empty moments.
    ///
    /// Each lane is one pixel, so a window offset `(dx, dy)` is one 8-lane step for the whole
    /// group, and the lanes come out as the group's moments with no reduction across lanes.
    #[inline(always)]
    pub fn group_moments(
        &self,
        x0: usize,
        y: usize,
        half: &[usize; GROUP],
        radius_m: f64,
    ) -> GroupMoments {
        let mut acc = [[0f32; GROUP]; 10];
        let reach = half.iter().copied().max().unwrap_or(0).min(MAX_PACKED_HALF);
        if y >= self.height || x0 >= self.width {
            return acc;
        }
        let r2 = (radius_m * radius_m) as f32;
        let mut count = [0u32; GROUP];
        let centre = self.stride * y + PAD_LEFT + x0;
        let p = [0, 1, 2].map(|c| *lanes(&self.xyz[c], centre));
        // Per ring of window offsets (Chebyshev distance c = max(|dx|, |dy|)) and lane, the
        // largest squared distance kept: r² inside the lane's window, −1 (nothing) outside it.
        let limit: [[f32; GROUP]; MAX_PACKED_HALF + 1] =
            from_fn(|c| from_fn(|l| if c <= half[l] { r2 } else { -1.0 }));
        // Where every lane with a point has the group's reach (most groups: all pixels of the
        // group are nearer than radius · fx / 7), every offset's limit is r² in every lane;
        // else the limits of each row of the window, by column offset, are built per row. Either
        // way the offsets' loop runs over iterators alone, with no index to check.
        let uniform = (0..GROUP).all(|l| half[l] == reach || p[2][l].is_nan());
        let same = [r2; GROUP];
        let mut row_limit = [same; 2 * MAX_PACKED_HALF + 1];
        for yy in y.saturating_sub(reach)..(y + reach + 1).min(self.height) {
            if !uniform {
                ring_limits(&limit, yy.abs_diff(y), reach, &mut row_limit);
            }
            let offsets = self.row_windows(x0, yy, reach);
            if uniform {
                for q in offsets {
                    accumulate(&mut count, &mut acc, q, &p, &same);
                }
            } else {
                for (q, lim) in offsets.zip(&row_limit[..=2 * reach]) {
                    accumulate(&mut count, &mut acc, q, &p, lim);
                }
            }
        }
        acc[0] = count.map(|c| c as f32);
        acc
    }
}

impl PackedPoints {
    /// Row `yy` of the window of the group at `x0` with reach `reach` (columns x0 − reach …
    /// x0 + reach + 7, inside the padding): for each column offset, the 8 lanes' points' x, y
    /// and z, by iterators alone (no index to check).
    #[inline(always)]
    pub(super) fn row_windows(
        &self,
        x0: usize,
        yy: usize,
        reach: usize,
    ) -> impl Iterator<Item = [&[f32; GROUP]; 3]> {
        let first = self.stride * yy + PAD_LEFT + x0 - reach;
        let span = 2 * reach + GROUP;
        let [xs, ys, zs] = [0, 1, 2].map(|c| &self.xyz[c][first..first + span]);
        xs.windows(GROUP)
            .zip(ys.windows(GROUP))
            .zip(zs.windows(GROUP))
            .map(|((qx, qy), qz)| [as_lanes(qx), as_lanes(qy), as_lanes(qz)])
    }
}

/// The limits of a window row `dy` from the centre, by column offset `dx` (`0 ..= 2·reach`):
/// the limit of the ring (Chebyshev distance) the offset lies on.
#[inline(always)]
pub(super) fn ring_limits<L: Copy>(
    rings: &[L; MAX_PACKED_HALF + 1],
    dy: usize,
    reach: usize,
    out: &mut [L; 2 * MAX_PACKED_HALF + 1],
) {
    for (dx, lim) in out[..=2 * reach].iter_mut().enumerate() {
        *lim = rings[dy.max(dx.abs_diff(reach))];
    }
}

/// A window of [`GROUP`] values as an array (the windows' length is known, so nothing is
/// checked at run time).
#[inline(always)]
pub(super) fn as_lanes(v: &[f32]) -> &[f32; GROUP] {
    v.first_chunk::<GROUP>()
        .expect("windows hold whole groups; this is a bug")
}

/// The 8 values of `v` from `start`.
#[inline(always)]
pub(super) fn lanes(v: &[f32], start: usize) -> &[f32; GROUP] {
    v[start..]
        .first_chunk::<GROUP>()
        .expect("padded rows hold whole groups; this is a bug")
}

/// Adds one window offset to the lane accumulators (count, Σd, Σddᵀ): lane `l` takes `q[l]`
/// relative to `p[l]` if its squared distance is at most `limit[l]`.
#[inline(always)]
fn accumulate(
    count: &mut [u32; GROUP],
    acc: &mut GroupMoments,
    q: [&[f32; GROUP]; 3],
    p: &[[f32; GROUP]; 3],
    limit: &[f32; GROUP],
) {
    for l in 0..GROUP {
        let (dx, dy, dz) = (q[0][l] - p[0][l], q[1][l] - p[1][l], q[2][l] - p[2][l]);
        // NaN (invalid) points fail the comparison; rejected lanes add zeros.
        let keep = mul_add(dz, dz, mul_add(dy, dy, dx * dx)) <= limit[l];
        let mask = if keep { u32::MAX } else { 0 };
        let [dx, dy, dz] = [dx, dy, dz].map(|v| f32::from_bits(v.to_bits() & mask));
        // The count in integer lanes (the mask is −1 where kept) saves a register over adding
        // a masked 1.0.
        count[l] = count[l].wrapping_sub(mask);
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

/// `a·b + c` as a multiply and an add, never fused: the same bits on every CPU, whichever
/// version of the kernel runs (a software `fma` on a CPU without it would be far slower).
#[inline(always)]
fn mul_add(a: f32, b: f32, c: f32) -> f32 {
    a * b + c
}

/// Lane `l` of a group's moments, in f64.
#[inline(always)]
fn lane_moments(acc: &GroupMoments, l: usize) -> Moments {
    let v = |i: usize| f64::from(acc[i][l]);
    Moments {
        count: acc[0][l] as u32,
        sum: Vec3::new(v(1), v(2), v(3)),
        sum_sq: [v(4), v(5), v(6), v(7), v(8), v(9)],
    }
}

/// Per-pixel local planes: the neighbourhood's mean point and its LS normal.
#[derive(Debug, Clone, Default, PartialEq)]
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
    let mut out = LocalPlanes::default();
    local_planes_into(points, fx_px, hood, &mut PackedPoints::default(), &mut out);
    out
}

/// [`local_planes`] into `out`, whose grids take the size of `points`, with `packed` as the
/// packed copy of the points: both keep their buffers, so a caller that reuses them from frame
/// to frame allocates nothing once they have reached the frame's size.
///
/// ```
/// use tre_core::geometry::normals::{local_planes_into, PackedPoints};
/// use tre_core::geometry::normals::{local_planes, LocalPlanes, Neighbourhood};
/// use tre_core::geometry::{Grid, Intrinsics};
/// let k = Intrinsics::from_hfov(12, 10, 60.0).unwrap();
/// let points = k.back_project_map(&Grid::from_fn(12, 10, |x, _| 1.0 + 0.01 * x as f64));
/// let (mut packed, mut out) = (PackedPoints::default(), LocalPlanes::default());
/// for _ in 0..2 {
///     local_planes_into(&points, k.fx_px, &Neighbourhood::default(), &mut packed, &mut out);
/// }
/// assert_eq!(out, local_planes(&points, k.fx_px, &Neighbourhood::default()));
/// ```
pub fn local_planes_into(
    points: &PointMap,
    fx_px: f64,
    hood: &Neighbourhood,
    packed: &mut PackedPoints,
    out: &mut LocalPlanes,
) {
    let (w, h) = points.size();
    packed.pack(points);
    let packed = &*packed;
    out.centroid.reset(w, h, INVALID_POINT);
    out.normal.reset(w, h, INVALID_POINT);
    out.centroid
        .par_rows_mut()
        .zip(out.normal.par_rows_mut())
        .for_each(|((y, c_row), (_, n_row))| {
            let rows = RowOut { y, c_row, n_row };
            local_planes_row(packed, points, fx_px, hood, rows);
        });
}

/// One output row of [`local_planes_into`]: the centroids and, where `n_row` is not empty, the
/// normals of row `y`.
struct RowOut<'a> {
    y: usize,
    c_row: &'a mut [Vec3],
    n_row: &'a mut [Vec3],
}

/// Row `out.y` of [`local_planes_into`] (and of [`window_centroids_into`], which passes an
/// empty `n_row` and gets the centroids only), eight pixels at a time. Compiled twice, for
/// baseline x86-64 and for AVX2 + FMA, and the CPU's version is chosen at run time
/// ([`super::simd`]); both give the same bits.
#[multiversion(targets("x86_64+avx2+fma"))]
fn local_planes_row<'a>(
    packed: &PackedPoints,
    points: &PointMap,
    fx_px: f64,
    hood: &Neighbourhood,
    out: RowOut<'a>,
) {
    let RowOut { y, c_row, n_row } = out;
    let with_normals = !n_row.is_empty();
    for x0 in (0..c_row.len()).step_by(GROUP) {
        let group = hood.group_moments(packed, points, fx_px, x0, y);
        let fits = if with_normals {
            fit_normals(&group)
        } else {
            [None; GROUP]
        };
        for (l, (m, fit)) in group.iter().zip(fits).enumerate() {
            let x = x0 + l;
            let Some(p) = points.row(y).get(x) else { break };
            let Some(c) = m.mean(p) else { continue };
            c_row[x] = c;
            if with_normals {
                let n = match fit {
                    Some(n) => Some(orient_towards_camera(&n, p)),
                    None => normal_from_moments(points, m, x, y),
                };
                n_row[x] = n.unwrap_or(INVALID_POINT);
            }
        }
    }
}

/// LS normals oriented towards the camera (NaN where none can be fitted).
pub fn ls_normals(points: &PointMap, fx_px: f64, hood: &Neighbourhood) -> Grid<Vec3> {
    local_planes(points, fx_px, hood).normal
}

/// Window centroids only (cheaper than [`local_planes`] when normals come from elsewhere).
pub fn window_centroids(points: &PointMap, fx_px: f64, hood: &Neighbourhood) -> PointMap {
    let mut out = PointMap::default();
    window_centroids_into(points, fx_px, hood, &mut PackedPoints::default(), &mut out);
    out
}

/// [`window_centroids`] into `out` (resized to the size of `points`), with `packed` as the
/// packed copy of the points; both keep their buffers, as in [`local_planes_into`].
///
/// ```
/// use tre_core::geometry::normals::{window_centroids_into, PackedPoints};
/// use tre_core::geometry::normals::{window_centroids, Neighbourhood};
/// use tre_core::geometry::{Grid, Intrinsics, PointMap};
/// let k = Intrinsics::from_hfov(9, 8, 60.0).unwrap();
/// let points = k.back_project_map(&Grid::from_fn(9, 8, |_, y| 1.0 + 0.02 * y as f64));
/// let (mut packed, mut out) = (PackedPoints::default(), PointMap::default());
/// window_centroids_into(&points, k.fx_px, &Neighbourhood::default(), &mut packed, &mut out);
/// assert_eq!(out, window_centroids(&points, k.fx_px, &Neighbourhood::default()));
/// ```
pub fn window_centroids_into(
    points: &PointMap,
    fx_px: f64,
    hood: &Neighbourhood,
    packed: &mut PackedPoints,
    out: &mut PointMap,
) {
    let (w, h) = points.size();
    packed.pack(points);
    let packed = &*packed;
    out.reset(w, h, INVALID_POINT);
    out.par_rows_mut().for_each(|(y, c_row)| {
        let rows = RowOut {
            y,
            c_row,
            n_row: &mut [],
        };
        local_planes_row(packed, points, fx_px, hood, rows);
    });
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Asserts that packed moments `a` match the f64 reference `b`.
    fn assert_close(a: &Moments, b: &Moments, what: &str) {
        assert_eq!(a.count, b.count, "{what}");
        // f32 coordinates carry ~1e-7 m of rounding; means agree to well under 1e-6 m.
        let n = f64::from(a.count.max(1));
        assert!((a.sum - b.sum).norm() / n < 5e-7, "{what}");
        for (p, q) in a.sum_sq.iter().zip(b.sum_sq) {
            assert!((p - q).abs() / n < 1e-8, "{what}");
        }
    }

    #[test]
    fn group_lanes_match_the_f64_reference_with_a_half_width_each() {
        // A dense bumpy surface 3 m away: every point of a 15 × 15 window lies within R, so a
        // lane adds 225 points.
        let (w, h) = (37, 21);
        let pts = Grid::from_fn(w, h, |x, y| {
            if (x * 5 + y * 3) % 13 == 0 {
                INVALID_POINT
            } else {
                let (u, v) = (x as f64 * 0.003, y as f64 * 0.003);
                Vec3::new(u - 0.05, v + 0.4, 3.0 + 0.004 * (u * 300.0).sin() + 0.2 * v)
            }
        });
        let mut packed = PackedPoints::default();
        packed.pack(&pts);
        let mut full_lanes = 0;
        for x0 in [0, 3, 16, w - 5, w - 1] {
            for y in [0, 2, 10, h - 1] {
                // Mixed half-widths, then one for all lanes (the kernel's uniform path).
                let mixed: [usize; GROUP] = std::array::from_fn(|l| (l + x0 + y) % GROUP);
                for half in [mixed, [7; GROUP], [(x0 + y) % 7 + 1; GROUP]] {
                    let group = packed.group_moments(x0, y, &half, 0.05);
                    for (l, &hl) in half.iter().enumerate() {
                        let a = lane_moments(&group, l);
                        let x = x0 + l;
                        // Half-width 0 is the pixel's own point only; past the row, nothing.
                        let b = match x < w {
                            true => window_moments(&pts, x, y, hl, 0.05 * 0.05),
                            false => Moments::default(),
                        };
                        full_lanes += usize::from(b.count > 200);
                        assert_close(&a, &b, &format!("({x}, {y}) h {hl}"));
                    }
                }
            }
        }
        assert!(
            full_lanes > 0,
            "some lane must add most of a 15 × 15 window"
        );
    }

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
                // The pixel alone in lane 0 of its group.
                let mut halves = [0; GROUP];
                halves[0] = half;
                let a = lane_moments(&packed.group_moments(x, y, &halves, 0.05), 0);
                let b = window_moments(&pts, x, y, half, 0.05 * 0.05);
                assert_close(&a, &b, &format!("({x}, {y}) h {half}"));
            }
        }
    }
}
