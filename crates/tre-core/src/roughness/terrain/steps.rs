//! The step term of the terrain estimate: the seams right of and below each pixel, each side's
//! evidence, and the offset between the sides along their pooled normal (docs/terrain.md).

use super::{Frame, Support};
use crate::geometry::{covariance_lanes, Moments, SymLanes, Vec3};

/// Scatter off a support's plane, beyond the noise, below which it holds no step, metres.
const PLANAR_M: f64 = 0.002;

impl Frame<'_> {
    /// The seams right of and below pixel `xy` (point `p`, support `s`) that hold evidence on
    /// both sides, pushed onto `seams`; and the steps' noise σ the support predicts (the
    /// margin a step must clear, before the seams' own).
    pub(super) fn seams(
        &self,
        xy: (usize, usize),
        p: &Vec3,
        s: &Support,
        seams: &mut Vec<Seam>,
    ) -> f64 {
        let (x, y) = (xy.0 as isize, xy.1 as isize);
        let r = s.half as isize;
        // Each seam's two sides, and the image rows each side spans (the scan lines its
        // registration offsets average over).
        let sides = [
            (
                ((x - r, y - r), (x + 1, y + r + 1)),
                ((x + 1, y - r), (x + r + 2, y + r + 1)),
                2.0 * r as f64 + 1.0,
            ),
            (
                ((x - r, y - r), (x + r + 1, y + 1)),
                ((x - r, y + 1), (x + r + 1, y + r + 2)),
                r as f64 + 1.0,
            ),
        ];
        // The noise as the support predicts it for two halves of itself (measured on the seams
        // below where they are looked at). Two halves' centroids lie √3·σ apart along the
        // window's longer in-plane axis (a uniform spread): metres of ground at grazing views.
        let reach2 = 3.0 * s.l_max;
        let noise2 = s.sigma_n * s.sigma_n + s.sigma_c * s.sigma_c;
        let lines = s.half as f64 + 1.0;
        let e_j = (s.sigma_n.powi(2) * 2.0 * self.mean_var(0.5 * s.count)
            + 2.0 * s.sigma_c.powi(2) / lines
            + s.tilt2(self.mean_var(s.count)) * reach2)
            .sqrt();
        // A support whose points lie on its plane within twice the noise (and 2 mm) holds no
        // step the margin would let through: its seams need no look.
        if s.l_min <= 4.0 * noise2 + PLANAR_M * PLANAR_M {
            return e_j;
        }
        let min_side = (self.cfg.min_points / 2).max(3);
        let extent = s.half as f64 * p.z / self.fx_px;
        for ((a0, a1), (b0, b1), lines) in sides {
            let (a, b) = (self.sums.rect(a0, a1), self.sums.rect(b0, b1));
            if a.count < min_side || b.count < min_side {
                continue;
            }
            let (na, nb) = (f64::from(a.count), f64::from(b.count));
            let covs = covariance_lanes(&[a, b]);
            let pooled: SymLanes<1> =
                std::array::from_fn(|e| [(na * covs[e][0] + nb * covs[e][1]) / (na + nb)]);
            // Half the trace bounds the middle eigenvalue: a pooled scatter that cannot pass
            // the spread test needs no solve.
            let solve = may_spread(&pooled, 0.0625 * extent * extent);
            seams.push(Seam {
                x: xy.0,
                a,
                b,
                lines,
                extent,
                pooled,
                solve,
            });
        }
        e_j
    }
}

/// Whether a covariance's middle eigenvalue can reach `l_mid`: it is at most half the trace
/// (the other two are at least 0 and at least it), with room for the solver's rounding.
pub(super) fn may_spread(cov: &SymLanes<1>, l_mid: f64) -> bool {
    0.5 * (cov[0][0] + cov[3][0] + cov[5][0]) * (1.0 + 1e-9) >= l_mid
}

/// The largest angle between the pooled normal of a step's two sides and the support's: a
/// real step tilts the support's plane by less; two sides that are each a fronto-parallel
/// terrace of quantised disparity (passive stereo) pool to the viewing axis, far more.
const MAX_POOLED_TILT_DEG: f64 = 30.0;

/// A seam with evidence on both sides: its pixel's column, its two sides' moments, the image
/// rows each side spans (a registration offset is shared by a scan line, so a side's mean
/// averages the offsets of its lines), the support's half-width in metres, the sides' pooled
/// scatter (each about its own centroid) and whether that may pass the spread test.
#[derive(Debug, Clone, Copy)]
pub(super) struct Seam {
    pub(super) x: usize,
    a: Moments,
    b: Moments,
    lines: f64,
    extent: f64,
    pub(super) pooled: SymLanes<1>,
    pub(super) solve: bool,
}

/// The offset between a seam's two sides' centroids along their pooled normal (`plane`, its
/// pooled scatter's, `None` where not solved), and its noise σ. Where the pooled scatter is
/// not spread in two directions (each side one scan line, say: then any direction across the
/// lines fits) or tilts from the support's normal by more than [`MAX_POOLED_TILT_DEG`], the
/// support's normal stands in; `conditioning` is the support's test.
pub(super) fn pooled_step(
    seam: &Seam,
    plane: Option<(Vec3, f64, f64)>,
    mean_var: &dyn Fn(f64) -> f64,
    s: &Support,
    conditioning: f64,
) -> (f64, f64) {
    let (a, b) = (&seam.a, &seam.b);
    let (na, nb) = (f64::from(a.count), f64::from(b.count));
    let (normal, spread, count) = match plane {
        Some((n, l_min, l_mid))
            if l_mid >= conditioning * l_min
                && l_mid.sqrt() >= 0.25 * seam.extent
                && n.dot(&s.normal).abs() >= MAX_POOLED_TILT_DEG.to_radians().cos() =>
        {
            (n, l_mid, na + nb)
        }
        _ => (s.normal, s.l_mid, s.count),
    };
    let delta = b.sum / nb - a.sum / na;
    let offset = delta.dot(&normal).abs();
    // The normal's own error tilts the offset by its angle times the sides' distance along the
    // plane (large at grazing views, where a window spans metres of ground).
    let tilt2 = s.tilt2(mean_var(count)) * s.l_mid / spread.max(f64::MIN_POSITIVE);
    let along2 = (delta.norm_squared() - offset * offset).max(0.0);
    let sides = mean_var(na) + mean_var(nb);
    let registration2 = 2.0 * s.sigma_c.powi(2) / seam.lines;
    let e = (s.sigma_n.powi(2) * sides + registration2 + tilt2 * along2).sqrt();
    (offset, e)
}
