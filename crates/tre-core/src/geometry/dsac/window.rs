//! The padded point planes and a pixel's 7×7 window over them: candidates, validity, hypothesis planes in f32, the scorer's blocks.

use super::*;

/// The point map as three coordinate planes padded by [`RADIUS`] invalid pixels on every side,
/// so that every window is read without bounds checks; invalid points are NaN, so that a point
/// is valid exactly when its z is positive.
#[derive(Debug, Default)]
pub(super) struct PaddedPoints {
    pub(super) stride: usize,
    pub(super) planes: [Vec<f64>; 3],
}

impl PaddedPoints {
    pub(super) fn new(points: &PointMap) -> Self {
        let mut padded = Self::default();
        padded.pack(points);
        padded
    }

    /// Copies `points` in, reusing this buffer's allocations.
    pub(super) fn pack(&mut self, points: &PointMap) {
        let (w, h) = points.size();
        self.stride = w + 2 * RADIUS;
        let stride = self.stride;
        for (a, plane) in self.planes.iter_mut().enumerate() {
            plane.clear();
            plane.resize(stride * (h + 2 * RADIUS), f64::NAN);
            plane
                .par_chunks_mut(stride)
                .skip(RADIUS)
                .take(h)
                .enumerate()
                .for_each(|(y, row)| {
                    for (dst, p) in row[RADIUS..].iter_mut().zip(points.row(y)) {
                        *dst = if is_valid_point(p) { p[a] } else { f64::NAN };
                    }
                });
        }
    }

    /// A 7 × 7 map holding `cands`, whose window at `(RADIUS, RADIUS)` is theirs.
    pub(super) fn of_candidates(cands: &[Vec3; CANDIDATES]) -> Self {
        Self::new(&Grid::from_fn(WINDOW, WINDOW, |x, y| cands[y * WINDOW + x]))
    }

    /// Whether pixel `(x, y)` holds a valid point.
    #[inline(always)]
    pub(super) fn is_valid(&self, x: usize, y: usize) -> bool {
        self.planes[2][(y + RADIUS) * self.stride + x + RADIUS] > 0.0
    }
}

/// One pixel's candidates: f32 lane arrays (candidate `k` in lane `k`; the lanes after the 49th
/// are padding and invalid) and the way back to their f64 points.
pub(super) struct Window<'a> {
    pub(super) points: &'a PaddedPoints,
    /// Index of candidate 0 in the padded planes.
    pub(super) base: usize,
    /// Coordinates relative to `origin`, rounded to f32; 0 for invalid candidates.
    pub(super) rel: [[f32; LANES]; 3],
    /// All bits set for valid candidates, 0 otherwise.
    pub(super) valid: [u32; LANES],
    /// After block `b`: the number of valid candidates in later blocks.
    pub(super) to_come: [f32; BLOCKS],
    /// The centre point (the camera origin if the centre is invalid).
    pub(super) origin: Vec3,
}

impl<'a> Window<'a> {
    /// The window centred on pixel `(x, y)`.
    #[inline(always)]
    pub(super) fn new(points: &'a PaddedPoints, x: usize, y: usize) -> Self {
        let base = y * points.stride + x;
        let centre = base + RADIUS * points.stride + RADIUS;
        let c = points.planes.each_ref().map(|p| p[centre]);
        let origin = if c[2] > 0.0 {
            Vec3::from(c)
        } else {
            Vec3::zeros()
        };
        let mut valid = [0; LANES];
        let mut rel = [[0.0; LANES]; 3];
        for r in 0..WINDOW {
            let src = base + r * points.stride..base + r * points.stride + WINDOW;
            let lanes = r * WINDOW..(r + 1) * WINDOW;
            for (v, &z) in valid[lanes.clone()]
                .iter_mut()
                .zip(&points.planes[2][src.clone()])
            {
                *v = if z > 0.0 { u32::MAX } else { 0 };
            }
            for (a, plane) in points.planes.iter().enumerate() {
                let dst = rel[a][lanes.clone()].iter_mut().zip(&valid[lanes.clone()]);
                for ((d, &m), &q) in dst.zip(&plane[src.clone()]) {
                    *d = f32::from_bits(((q - origin[a]) as f32).to_bits() & m);
                }
            }
        }
        let mut to_come = [0.0; BLOCKS];
        for b in (0..BLOCKS - 1).rev() {
            let next = &valid[(b + 1) * BLOCK..(b + 2) * BLOCK];
            to_come[b] = to_come[b + 1] + next.iter().filter(|&&v| v != 0).count() as f32;
        }
        Self {
            points,
            base,
            rel,
            valid,
            to_come,
            origin,
        }
    }

    /// Candidate `k`'s point.
    #[inline(always)]
    pub(super) fn point(&self, k: usize) -> Vec3 {
        let i = self.base + (k / WINDOW) * self.points.stride + k % WINDOW;
        Vec3::from(self.points.planes.each_ref().map(|p| p[i]))
    }

    /// `plane` in the scorer's f32 form.
    #[inline(always)]
    pub(super) fn hyp32(&self, plane: &Plane, scorer: &Scorer) -> Hyp32 {
        let m = plane.normal * scorer.gain;
        let u = plane.centroid - self.origin;
        let o = (m.x * u.x + m.y * u.y) + m.z * u.z;
        Hyp32 {
            n: [m.x as f32, m.y as f32, m.z as f32],
            o: o as f32,
            tau: scorer.tau,
        }
    }

    /// Adds blocks `blocks` of `h`'s soft inlier terms to the lane accumulators `acc`.
    #[inline(always)]
    pub(super) fn add_blocks(
        &self,
        h: &Hyp32,
        acc: &mut [f32; BLOCK],
        blocks: std::ops::Range<usize>,
    ) {
        let [nx, ny, nz] = h.n;
        let [rx, ry, rz] = &self.rel;
        for b in blocks {
            for (l, a) in acc.iter_mut().enumerate() {
                let k = b * BLOCK + l;
                let s = (nx * rx[k] + ny * ry[k]) + nz * rz[k] - h.o;
                let v = recip_one_plus_exp2(s.abs() - h.tau);
                *a += f32::from_bits(v.to_bits() & self.valid[k]);
            }
        }
    }

    /// The f32 soft inlier count of `h` over the valid candidates (module docs, step 4).
    #[inline(always)]
    pub(super) fn full_score(&self, h: &Hyp32) -> f32 {
        let mut acc = [0.0; BLOCK];
        self.add_blocks(h, &mut acc, 0..BLOCKS);
        sum_block(acc)
    }

    /// The score of `h` from its accumulators after [`LEAD_BLOCKS`] blocks, or `None` once it
    /// provably is below `floor`: the partial sum plus `most` ([`Scorer::most`]) per valid
    /// candidate still to come, plus [`PRUNE_MARGIN`] for the f32 rounding of the sums (at most
    /// 56 · 10 · 2⁻²⁴ relative), bounds it from above.
    #[inline(always)]
    pub(super) fn finish_above(
        &self,
        h: &Hyp32,
        mut acc: [f32; BLOCK],
        floor: f32,
        most: f32,
    ) -> Option<f32> {
        for b in LEAD_BLOCKS..BLOCKS {
            if sum_block(acc) + (self.to_come[b - 1] * most + PRUNE_MARGIN) <= floor {
                return None;
            }
            self.add_blocks(h, &mut acc, b..b + 1);
        }
        Some(sum_block(acc))
    }

    /// What the LS refit on the inliers of `plane` needs ([`inlier_moments`]).
    pub(super) fn refit_input(&self, plane: &Plane, tau_m: f64) -> Refit {
        let [moments] = inlier_moments(self.points, self.base, &[*plane], &[self.origin], tau_m);
        Refit {
            moments,
            hypothesis: plane.normal,
            origin: self.origin,
        }
    }
}
