//! Neighbour counts: at each valid pixel, the valid points within a radius of its point in its
//! pixel window, in f64 as the per-point definition ([`count_within`]) computes them, eight
//! pixels at a time.
//!
//! The counts feed the uncertainty map (the surface term's residual), so they must be the
//! definition's exactly: each lane computes `(q − p)·(q − p)` with the same f64 operations in
//! the same order as `nalgebra`'s `norm_squared` (`(dx² + dy²) + dz²`, no fused multiply-add),
//! and compares it with r² as the definition does. Only the order of the pixels changes.

use multiversion::multiversion;
use rayon::prelude::*;

use super::camera::{is_valid_point, PointMap};
use super::normals::Neighbourhood;
use super::simd::from_fn;
use super::Grid;

/// Pixels per group: one lane each (two AVX2 registers of f64).
const GROUP: usize = 8;
/// Widest half-width the packed kernel handles; wider windows take [`count_within`].
const MAX_PACKED_HALF: usize = 7;
/// Invalid columns left of each packed row: a window reaches 7 columns left.
const PAD_LEFT: usize = 8;
/// Invalid columns right of each packed row: a group's last pixel plus the 7 columns its window
/// reaches, rounded up.
const PAD_RIGHT: usize = 16;

/// Points as f64 structure-of-arrays rows padded with NaN columns (invalid points are NaN too),
/// so that the count kernel reads whole 8-lane chunks with no border cases.
#[derive(Debug, Clone, Default)]
pub struct PackedPoints64 {
    width: usize,
    height: usize,
    stride: usize,
    xyz: [Vec<f64>; 3],
}

impl PackedPoints64 {
    /// Packs `points` (reusing this buffer's allocations).
    pub fn pack(&mut self, points: &PointMap) {
        let (w, h) = points.size();
        (self.width, self.height, self.stride) = (w, h, PAD_LEFT + w + PAD_RIGHT);
        for (c, buf) in self.xyz.iter_mut().enumerate() {
            buf.clear();
            buf.resize(self.stride * h, f64::NAN);
            buf.par_chunks_mut(self.stride.max(1))
                .enumerate()
                .for_each(|(y, row)| {
                    for (dst, p) in row[PAD_LEFT..PAD_LEFT + w].iter_mut().zip(points.row(y)) {
                        *dst = if is_valid_point(p) { p[c] } else { f64::NAN };
                    }
                });
        }
    }

    /// The counts of the pixels `(x0 + l, y)`: the points within `sqrt(r2)` in the window of
    /// half-width `half[l]` (at most 7), the pixel's own included; 0 for invalid pixels and
    /// lanes past the row's end.
    #[inline(always)]
    fn group_counts(&self, x0: usize, y: usize, half: &[usize; GROUP], r2: f64) -> [u64; GROUP] {
        // In 64-bit lanes, as wide as the f64 comparisons' masks: no packing per offset.
        let mut count = [0u64; GROUP];
        let reach = half.iter().copied().max().unwrap_or(0).min(MAX_PACKED_HALF);
        let centre = self.stride * y + PAD_LEFT + x0;
        let p: [[f64; GROUP]; 3] = from_fn(|c| *lanes(&self.xyz[c][centre..]));
        // Per ring of offsets (Chebyshev distance) and lane: r² inside the lane's window, −1
        // (nothing passes) outside it.
        let limit: [[f64; GROUP]; MAX_PACKED_HALF + 1] =
            from_fn(|c| from_fn(|l| if c <= half[l] { r2 } else { -1.0 }));
        // As in the LS kernel: one limit for all offsets where every lane with a point has the
        // group's reach, else the limits of each row built per row.
        let uniform = (0..GROUP).all(|l| half[l] == reach || p[2][l].is_nan());
        let same = [r2; GROUP];
        let mut row_limit = [same; 2 * MAX_PACKED_HALF + 1];
        for yy in y.saturating_sub(reach)..(y + reach + 1).min(self.height) {
            let dy = yy.abs_diff(y);
            if !uniform {
                for (dx, lim) in row_limit[..=2 * reach].iter_mut().enumerate() {
                    *lim = limit[dy.max(dx.abs_diff(reach))];
                }
            }
            let first = self.stride * yy + PAD_LEFT + x0 - reach;
            let span = 2 * reach + GROUP;
            let [xs, ys, zs] = [0, 1, 2].map(|c| &self.xyz[c][first..first + span]);
            let offsets = xs
                .windows(GROUP)
                .zip(ys.windows(GROUP))
                .zip(zs.windows(GROUP));
            if uniform {
                for ((qx, qy), qz) in offsets {
                    add_within(&mut count, [lanes(qx), lanes(qy), lanes(qz)], &p, &same);
                }
            } else {
                for (((qx, qy), qz), lim) in offsets.zip(&row_limit[..=2 * reach]) {
                    add_within(&mut count, [lanes(qx), lanes(qy), lanes(qz)], &p, lim);
                }
            }
        }
        count
    }
}

/// Counts, in each lane `l`, the point `q[l]` if its squared distance from `p[l]` is at most
/// `limit[l]`.
#[inline(always)]
fn add_within(
    count: &mut [u64; GROUP],
    q: [&[f64; GROUP]; 3],
    p: &[[f64; GROUP]; 3],
    limit: &[f64; GROUP],
) {
    for l in 0..GROUP {
        let (dx, dy, dz) = (q[0][l] - p[0][l], q[1][l] - p[1][l], q[2][l] - p[2][l]);
        // nalgebra's norm_squared: (dx·dx + dy·dy) + dz·dz. NaN fails the test.
        let d2 = dx * dx + dy * dy + dz * dz;
        // The comparison's mask (all ones where kept) subtracted: a count in 64-bit lanes.
        count[l] = count[l].wrapping_sub(u64::from(d2 <= limit[l]).wrapping_neg());
    }
}

/// The first [`GROUP`] values of `v` as an array.
#[inline(always)]
fn lanes(v: &[f64]) -> &[f64; GROUP] {
    v.first_chunk::<GROUP>()
        .expect("padded rows hold whole groups; this is a bug")
}

/// Valid points within `radius_m` of pixel `(x, y)`'s point in its window of half-width `half`
/// (the definition; the pixel's own point included).
///
/// ```
/// use tre_core::geometry::neighbours::count_within;
/// use tre_core::geometry::{Grid, Vec3};
/// let points = Grid::from_fn(5, 5, |x, y| Vec3::new(0.01 * x as f64, 0.01 * y as f64, 1.0));
/// // Within 1.5 cm of the centre: itself and its 4-neighbours and diagonal ones.
/// assert_eq!(count_within(&points, 2, 2, 2, 0.015), 9);
/// assert_eq!(count_within(&points, 0, 0, 1, 0.015), 4);
/// ```
pub fn count_within(points: &PointMap, x: usize, y: usize, half: usize, radius_m: f64) -> usize {
    let (w, h) = points.size();
    let p = points[(x, y)];
    let r2 = radius_m * radius_m;
    (y.saturating_sub(half)..(y + half + 1).min(h))
        .map(|yy| {
            points.row(yy)[x.saturating_sub(half)..(x + half + 1).min(w)]
                .iter()
                .filter(|q| (*q - p).norm_squared() <= r2)
                .count()
        })
        .sum()
}

/// [`count_within`] at every pixel with the window of [`Neighbourhood::half_width`] (0 where the
/// pixel is invalid), into `out`, with `packed` as the packed copy of the points; both keep
/// their buffers from call to call.
///
/// ```
/// use tre_core::geometry::neighbours::{count_within, neighbour_counts_into, PackedPoints64};
/// use tre_core::geometry::normals::Neighbourhood;
/// use tre_core::geometry::{Grid, Intrinsics};
/// let k = Intrinsics::from_hfov(21, 13, 60.0).unwrap();
/// let points = k.back_project_map(&Grid::from_fn(21, 13, |x, y| 0.5 + 0.01 * (x * y) as f64));
/// let hood = Neighbourhood::default();
/// let mut counts = Grid::new(0, 0, 0);
/// neighbour_counts_into(&points, k.fx_px, &hood, &mut PackedPoints64::default(), &mut counts);
/// let h = hood.half_width(k.fx_px, points[(20, 7)].z);
/// assert_eq!(counts[(20, 7)] as usize, count_within(&points, 20, 7, h, hood.radius_m));
/// ```
pub fn neighbour_counts_into(
    points: &PointMap,
    fx_px: f64,
    hood: &Neighbourhood,
    packed: &mut PackedPoints64,
    out: &mut Grid<u32>,
) {
    let (w, h) = points.size();
    packed.pack(points);
    let packed = &*packed;
    out.reset(w, h, 0);
    out.par_rows_mut()
        .for_each(|(y, row)| counts_row(packed, points, fx_px, hood, (y, row)));
}

/// Row `y` of [`neighbour_counts_into`], eight pixels at a time; compiled for baseline x86-64
/// and for AVX2 + FMA, chosen at run time ([`super::simd`]), both with the same results.
#[multiversion(targets("x86_64+avx2+fma"))]
fn counts_row(
    packed: &PackedPoints64,
    points: &PointMap,
    fx_px: f64,
    hood: &Neighbourhood,
    (y, row): (usize, &mut [u32]),
) {
    let r2 = hood.radius_m * hood.radius_m;
    let cells = points.row(y);
    for x0 in (0..row.len()).step_by(GROUP) {
        let mut half = [0; GROUP];
        for (h, p) in half.iter_mut().zip(&cells[x0..]) {
            if is_valid_point(p) {
                *h = hood.half_width(fx_px, p.z);
            }
        }
        let packed_half = half.map(|h| if h <= MAX_PACKED_HALF { h } else { 0 });
        let counts = packed.group_counts(x0, y, &packed_half, r2);
        for (l, (out, h)) in row[x0..].iter_mut().zip(half).enumerate() {
            *out = match h {
                0 => 0,
                h if h <= MAX_PACKED_HALF => counts[l] as u32,
                h => count_within(points, x0 + l, y, h, hood.radius_m) as u32,
            };
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::{Vec3, INVALID_POINT};

    /// Every pixel's count against the definition, on a bumpy surface with holes whose points
    /// sit at all distances around the radius, with every half-width from 1 to 9 (8 and 9 take
    /// the definition's path).
    #[test]
    fn counts_are_the_definitions_at_every_pixel() {
        let (w, h) = (45, 23);
        let points = Grid::from_fn(w, h, |x, y| {
            if (x * 7 + y * 3) % 13 == 0 {
                INVALID_POINT
            } else {
                let (u, v) = (x as f64 * 0.004, y as f64 * 0.005);
                Vec3::new(
                    u,
                    v,
                    0.4 + 0.03 * (u * 90.0).sin() + 0.2 * v + 0.1 * x as f64 / 45.0,
                )
            }
        });
        let mut packed = PackedPoints64::default();
        let mut counts = Grid::new(0, 0, 0);
        let mut seen = std::collections::BTreeSet::new();
        for max_half_width in [1, 3, 7, 9] {
            for radius_m in [0.01, 0.02, 0.05] {
                let hood = Neighbourhood {
                    radius_m,
                    max_half_width,
                };
                neighbour_counts_into(&points, 100.0, &hood, &mut packed, &mut counts);
                for y in 0..h {
                    for x in 0..w {
                        let p = points[(x, y)];
                        let want = match is_valid_point(&p) {
                            true => {
                                let half = hood.half_width(100.0, p.z);
                                count_within(&points, x, y, half, radius_m)
                            }
                            false => 0,
                        };
                        assert_eq!(counts[(x, y)] as usize, want, "({x}, {y}) {hood:?}");
                        seen.insert(want);
                    }
                }
            }
        }
        assert!(seen.len() > 30, "counts spread over {} values", seen.len());
    }
}
