//! Fig. 5, first stage: depth. The flat-ground prior from intrinsics and mounting, then the depth
//! net (`rgb` mode) or the sensor's depth resized nearest-neighbour (`rgbd`, `geometric`).

use rayon::prelude::*;

use tre_core::geometry::{Grid, Intrinsics, Mounting};

/// Prior depth where the ray through a pixel misses the ground (at or above the horizon),
/// metres; the same constant as the training code's `MAX_PRIOR_DEPTH_M`.
pub const MAX_PRIOR_DEPTH_M: f64 = 20.0;

/// Depth of flat ground seen by camera `k` mounted at `mounting`, for a `width × height` image.
///
/// With `y = (v − cy) / fy`, the gravity-down direction in the camera frame is
/// `(0, cos β, sin β)`, so the ray through `(u, v)` meets the ground at
/// `z = h / (y·cos β + sin β)`; where that denominator is not positive or `z` is not below
/// [`MAX_PRIOR_DEPTH_M`], [`MAX_PRIOR_DEPTH_M`]. It matches the training code's
/// `geometry.prior_depth`.
///
/// ```
/// use tre_core::geometry::{Intrinsics, Mounting};
/// use tre_pipeline::prior_depth;
/// let k = Intrinsics::new(100.0, 100.0, 50.0, 50.0).unwrap();
/// let prior = prior_depth(&k, &Mounting::default(), 101, 101);
/// // The optical axis meets the ground h / sin 60° in front of a camera 1 m up.
/// assert!((prior[(50, 50)] - 1.0 / 60f64.to_radians().sin()).abs() < 1e-12);
/// // A camera looking at the horizon sees the ground only below the image centre.
/// let level = Mounting::new(0.0, 1.0).unwrap();
/// assert_eq!(prior_depth(&k, &level, 101, 101)[(50, 10)], 20.0);
/// ```
pub fn prior_depth(k: &Intrinsics, mounting: &Mounting, width: usize, height: usize) -> Grid<f64> {
    let mut out = Grid::new(width, height, MAX_PRIOR_DEPTH_M);
    prior_depth_into(k, mounting, &mut out);
    out
}

/// [`prior_depth`] into a caller's buffer (its size is the image size), rows in parallel.
pub(crate) fn prior_depth_into(k: &Intrinsics, mounting: &Mounting, out: &mut Grid<f64>) {
    let width = out.width().max(1);
    let (sin, cos) = mounting.pitch_rad.sin_cos();
    out.as_mut_slice()
        .par_chunks_mut(width)
        .enumerate()
        .for_each(|(v, row)| {
            let y = (v as f64 - k.cy_px) / k.fy_px;
            let down = y * cos + sin;
            let z = mounting.height_m / down;
            let z = if down > 0.0 && z < MAX_PRIOR_DEPTH_M {
                z
            } else {
                MAX_PRIOR_DEPTH_M
            };
            row.fill(z);
        });
}
