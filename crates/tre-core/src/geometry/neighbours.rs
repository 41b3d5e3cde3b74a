//! Neighbour counts: at each valid pixel, the valid points within a radius of its point in its
//! pixel window, exactly as the per-point definition ([`count_within`], f64) counts them, eight
//! pixels at a time.
//!
//! The counts feed the uncertainty map (the surface term's residual), so they must be the
//! definition's to the last point. The kernel tests each point in f32 lanes against a band
//! around r² that is wider than any error f32 can make (`band_margin` in this file derives the
//! bound): a squared distance below the band's lower end is within the radius in f64 too, one
//! above its upper end is not.
//! A pixel with a point inside the band (rare: a point within a few micrometres of the radius)
//! is counted again by the definition. So every count is the definition's; a unit test checks
//! every pixel of surfaces whose points sit at all distances around the radius, and the real
//! frames' uncertainty maps are checked bit for bit (`tests/it/pipeline.rs`).

use multiversion::multiversion;
use rayon::prelude::*;

use super::camera::{is_valid_point, PointMap};
use super::normals::{lanes, ring_limits, Neighbourhood, PackedPoints};
use super::normals::{GROUP, MAX_PACKED_HALF, PAD_LEFT};
use super::simd::from_fn;
use super::{Grid, Vec3};

/// Per lane, the lower and upper ends of the band around r² ([`band_margin`]).
type Band = [[f32; GROUP]; 2];

/// The count kernel over the LS kernel's packed points (f32 structure-of-arrays rows padded
/// with NaN columns, each coordinate rounded to the nearest f32).
impl PackedPoints {
    /// For the pixels `(x0 + l, y)` with windows of half-width `half[l]` (at most 7): the
    /// points whose f32 squared distance is at most the band's lower end (sure), and at most
    /// its upper end (sure or in the band). Invalid pixels and lanes past the row's end count
    /// nothing.
    #[inline(always)]
    fn group_counts(
        &self,
        x0: usize,
        y: usize,
        half: &[usize; GROUP],
        band: &Band,
    ) -> [[u32; GROUP]; 2] {
        let (mut sure, mut maybe) = ([0u32; GROUP], [0u32; GROUP]);
        let reach = half.iter().copied().max().unwrap_or(0).min(MAX_PACKED_HALF);
        let centre = self.stride * y + PAD_LEFT + x0;
        let p: [[f32; GROUP]; 3] = from_fn(|c| *lanes(&self.xyz[c], centre));
        // Per ring of offsets (Chebyshev distance) and lane: the band inside the lane's window,
        // −1 (nothing passes) outside it.
        let limit: [Band; MAX_PACKED_HALF + 1] =
            from_fn(|c| from_fn(|e| from_fn(|l| if c <= half[l] { band[e][l] } else { -1.0 })));
        // Where every lane with a point has the group's reach, the band holds at every offset
        // and the table below stays as it starts; else each row's bands are built per row.
        let uniform = (0..GROUP).all(|l| half[l] == reach || p[2][l].is_nan());
        let mut row_limit = [*band; 2 * MAX_PACKED_HALF + 1];
        for yy in y.saturating_sub(reach)..(y + reach + 1).min(self.height) {
            if !uniform {
                ring_limits(&limit, yy.abs_diff(y), reach, &mut row_limit);
            }
            // One loop for both cases, the band read from the table in the uniform case too: a
            // loop of its own with the band in registers came out unrolled across offsets with
            // spills, slower.
            for (q, lim) in self
                .row_windows(x0, yy, reach)
                .zip(&row_limit[..=2 * reach])
            {
                add_within((&mut sure, &mut maybe), q, &p, lim);
            }
        }
        [sure, maybe]
    }
}

/// Counts, in each lane `l`, the point `q[l]` if its f32 squared distance from `p[l]` is at
/// most `lo[l]` (into `sure`) and at most `hi[l]` (into `maybe`).
#[inline(always)]
fn add_within(
    (sure, maybe): (&mut [u32; GROUP], &mut [u32; GROUP]),
    q: [&[f32; GROUP]; 3],
    p: &[[f32; GROUP]; 3],
    [lo, hi]: &Band,
) {
    let mut d2 = [0f32; GROUP];
    for l in 0..GROUP {
        let (dx, dy, dz) = (q[0][l] - p[0][l], q[1][l] - p[1][l], q[2][l] - p[2][l]);
        // Multiplies and adds, never fused: the same bits on every CPU. NaN passes nothing.
        d2[l] = dx * dx + dy * dy + dz * dz;
    }
    // The comparisons' masks (all ones where passed) subtracted: counts in integer lanes.
    for l in 0..GROUP {
        sure[l] = sure[l].wrapping_sub(u32::from(d2[l] <= lo[l]).wrapping_neg());
    }
    for l in 0..GROUP {
        maybe[l] = maybe[l].wrapping_sub(u32::from(d2[l] <= hi[l]).wrapping_neg());
    }
}

/// Half the width of the band around r² within which the f32 test of a point near `p` may
/// disagree with the f64 definition: twice the largest error, so that the band's ends rounded
/// to f32 still hold.
///
/// With u = 2⁻²⁴ and M the largest coordinate of `p` (in magnitude): rounding the coordinates to
/// f32 and subtracting them moves each component of a difference d by at most
/// δ = 2.1·u·(M + ρ), where ρ = 1.05·r + 3·u·M bounds |d| of any point the test can count; so
/// the exact sum of the f32 components' squares is within E = 3·δ·(2ρ + δ) of |d|². The f32
/// squares and sums add at most 3.1·u of it, and the f64 definition's own rounding 6·2⁻⁵³.
/// Hence a point whose f32 value is at most r² − m lies within r in f64, and one above r² + m
/// does not, for m ≥ E + 3.1·u·r² plus second-order terms; this returns 2·(E + 4·u·r²).
/// At 5 m from the camera with r = 5 cm, m ≈ 4·10⁻⁷ m², 0.016% of r².
fn band_margin(p: &Vec3, radius_m: f64) -> f64 {
    let u = f64::from(f32::EPSILON) / 2.0;
    let m = p.x.abs().max(p.y.abs()).max(p.z.abs());
    let rho = 1.05 * radius_m + 3.0 * u * m;
    let delta = 2.1 * u * (m + rho);
    2.0 * (3.0 * delta * (2.0 * rho + delta) + 4.0 * u * radius_m * radius_m)
}

/// Valid points within `radius_m` of pixel `(x, y)`'s point in its window of half-width `half`
/// (the definition; the pixel's own point included).
pub(crate) fn count_within(
    points: &PointMap,
    x: usize,
    y: usize,
    half: usize,
    radius_m: f64,
) -> usize {
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
pub(crate) fn neighbour_counts_into(
    points: &PointMap,
    fx_px: f64,
    hood: &Neighbourhood,
    packed: &mut PackedPoints,
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
    packed: &PackedPoints,
    points: &PointMap,
    fx_px: f64,
    hood: &Neighbourhood,
    (y, row): (usize, &mut [u32]),
) {
    let r2 = hood.radius_m * hood.radius_m;
    let cells = points.row(y);
    for x0 in (0..row.len()).step_by(GROUP) {
        let mut half = [0; GROUP];
        let mut band: Band = [[-1.0; GROUP]; 2];
        for (l, p) in cells[x0..].iter().take(GROUP).enumerate() {
            if is_valid_point(p) {
                half[l] = hood.half_width(fx_px, p.z);
                let m = band_margin(p, hood.radius_m);
                band[0][l] = (r2 - m) as f32;
                band[1][l] = (r2 + m) as f32;
            }
        }
        let packed_half = half.map(|h| if h <= MAX_PACKED_HALF { h } else { 0 });
        let [sure, maybe] = packed.group_counts(x0, y, &packed_half, &band);
        for (l, (out, h)) in row[x0..].iter_mut().zip(half).enumerate() {
            *out = match h {
                0 => 0,
                // No point in the band: every point's test agreed with f64.
                h if h <= MAX_PACKED_HALF && sure[l] == maybe[l] => sure[l],
                h => count_within(points, x0 + l, y, h, hood.radius_m) as u32,
            };
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::INVALID_POINT;

    #[test]
    fn count_within_counts_the_pixel_and_its_neighbours_in_reach() {
        let points = Grid::from_fn(5, 5, |x, y| {
            Vec3::new(0.01 * x as f64, 0.01 * y as f64, 1.0)
        });
        // Within 1.5 cm of the centre: itself and its 4-neighbours and diagonal ones.
        assert_eq!(count_within(&points, 2, 2, 2, 0.015), 9);
        assert_eq!(count_within(&points, 0, 0, 1, 0.015), 4);
    }

    #[test]
    fn neighbour_counts_are_count_within_in_the_hoods_window() {
        use crate::geometry::Intrinsics;
        let k = Intrinsics::from_hfov(21, 13, 60.0).unwrap();
        let points = k.back_project_map(&Grid::from_fn(21, 13, |x, y| 0.5 + 0.01 * (x * y) as f64));
        let hood = Neighbourhood::default();
        let mut counts = Grid::new(0, 0, 0);
        neighbour_counts_into(
            &points,
            k.fx_px,
            &hood,
            &mut PackedPoints::default(),
            &mut counts,
        );
        let h = hood.half_width(k.fx_px, points[(20, 7)].z);
        assert_eq!(
            counts[(20, 7)] as usize,
            count_within(&points, 20, 7, h, hood.radius_m)
        );
    }

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
        let mut packed = PackedPoints::default();
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

    /// Points at the radius to the last bits of f64: the f32 test cannot tell them, so they
    /// fall in the band, and the definition's count is the answer (one point nudged out by one
    /// ulp of its distance is left out, as f64 leaves it out).
    #[test]
    fn points_at_the_radius_fall_in_the_band_and_count_as_in_f64() {
        let r = 0.05;
        let p = Vec3::new(0.31, -0.17, 2.3);
        let (w, h) = (9, 3);
        let mut points = Grid::new(w, h, INVALID_POINT);
        points[(4, 1)] = p;
        // Neighbours along x at exactly r (as f64 rounds p.x + r), and one ulp beyond.
        points[(5, 1)] = Vec3::new(p.x + r, p.y, p.z);
        points[(3, 1)] = Vec3::new((p.x - r).next_down(), p.y, p.z);
        points[(4, 0)] = Vec3::new(p.x, p.y, p.z - r);
        let mut packed = PackedPoints::default();
        packed.pack(&points);
        let hood = Neighbourhood {
            radius_m: r,
            max_half_width: 7,
        };
        let m = band_margin(&p, r);
        let band = [[(r * r - m) as f32; GROUP], [(r * r + m) as f32; GROUP]];
        let mut half = [0; GROUP];
        half[0] = 1;
        let [sure, maybe] = packed.group_counts(4, 1, &half, &band);
        assert!(sure[0] < maybe[0], "sure {sure:?}, maybe {maybe:?}");
        let mut counts = Grid::new(0, 0, 0);
        neighbour_counts_into(&points, 1e3, &hood, &mut packed, &mut counts);
        let want = count_within(&points, 4, 1, 7, r);
        assert_eq!(counts[(4, 1)] as usize, want);
        // The pixel itself, and whichever of the three at r f64 keeps.
        let kept = [(5, 1), (3, 1), (4, 0)]
            .iter()
            .filter(|&&xy| (points[xy] - p).norm_squared() <= r * r)
            .count();
        assert_eq!(want, 1 + kept);
    }
}
