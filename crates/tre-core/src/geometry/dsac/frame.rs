//! The per-frame kernel: each pixel's best hypothesis, then the refits of a row's pixels eight at a time.

use super::*;

/// Everything the per-pixel kernel reads, shared by all rows.
pub(super) struct Frame<'a> {
    pub(super) points: &'a PaddedPoints,
    pub(super) logits: &'a [f32],
    pub(super) width: usize,
    pub(super) seed_key: u64,
    pub(super) cfg: &'a DsacConfig,
}

impl Frame<'_> {
    /// The best hypothesis plane of pixel `(x, y)` and the pixel's point, or `None` (invalid
    /// pixel, or no usable hypothesis).
    #[inline(always)]
    pub(super) fn pixel_best(&self, x: usize, y: usize) -> Option<(Plane, Vec3)> {
        if !self.points.is_valid(x, y) {
            return None;
        }
        let window = Window::new(self.points, x, y);
        let i = y * self.width + x;
        let plane_len = self.logits.len() / CANDIDATES;
        let mut lanes = [0.0; LANES];
        for (k, l) in lanes[..CANDIDATES].iter_mut().enumerate() {
            *l = self.logits[k * plane_len + i];
        }
        let cdf = Cdf::from_softmax(&softmax(&lanes, &window.valid));
        let stream = pixel_stream(self.seed_key, i as u64);
        let (_, plane) = best_hypothesis(&window, &cdf, stream, self.cfg, None)?;
        Some((plane, window.origin))
    }

    /// The DSAC normals of the pixels `(x0 + l, y)`, `l < REFIT_LANES` (`None` past the row's
    /// end, for invalid pixels and where no hypothesis is usable): best hypotheses pixel by
    /// pixel, then the refits' inlier moments and eigen-solves over the lanes.
    #[inline(always)]
    pub(super) fn group_normals(&self, x0: usize, y: usize) -> [Option<Vec3>; REFIT_LANES] {
        // A loop, not a closure: `pixel_best`, the bulk of the work, must inline into each
        // compiled version of the row kernel (`geometry::simd`), and a closure this large
        // is called, not inlined, from the unrolled loop of `from_fn`.
        let mut best: [Option<(Plane, Vec3)>; REFIT_LANES] = [None; REFIT_LANES];
        for (l, b) in best.iter_mut().enumerate() {
            if x0 + l < self.width {
                *b = self.pixel_best(x0 + l, y);
            }
        }
        let base = y * self.points.stride + x0;
        let tau = self.cfg.inlier_threshold_m;
        let moments: [Moments; REFIT_LANES] = if x0 + REFIT_LANES <= self.width {
            // Lanes without a plane get NaN ones: no inliers, and their moments are not used.
            let none = Plane {
                centroid: INVALID_POINT,
                normal: INVALID_POINT,
            };
            let planes = best.map(|b| b.map_or(none, |(p, _)| p));
            let origins = best.map(|b| b.map_or(INVALID_POINT, |(_, o)| o));
            // Four f64 lanes at a time, one AVX2 vector per sum: eight would not fit the registers.
            let mut moments = [Moments::default(); REFIT_LANES];
            for (h, m) in moments.chunks_exact_mut(MOMENT_LANES).enumerate() {
                let lanes = h * MOMENT_LANES..(h + 1) * MOMENT_LANES;
                m.copy_from_slice(&inlier_moments::<MOMENT_LANES>(
                    self.points,
                    base + h * MOMENT_LANES,
                    planes[lanes.clone()].try_into().expect("whole chunks"),
                    origins[lanes].try_into().expect("whole chunks"),
                    tau,
                ));
            }
            moments
        } else {
            // The row's last, partial group: its windows would reach past the padding.
            let mut moments = [Moments::default(); REFIT_LANES];
            for (l, (m, b)) in moments.iter_mut().zip(best).enumerate() {
                if let Some((p, o)) = b {
                    *m = inlier_moments(self.points, base + l, &[p], &[o], tau)[0];
                }
            }
            moments
        };
        let refits = from_fn(|l| {
            best[l].map(|(plane, origin)| Refit {
                moments: moments[l],
                hypothesis: plane.normal,
                origin,
            })
        });
        finish_refits(&refits)
    }
}
