//! Fig. 5, last stages: the local-plane centroid (centroid net, or the window mean) and
//! roughness by Eq. 1, `r = |n·(p − c)|`, with slope and traversability from the normals.

use ndarray::Array4;
use rayon::prelude::*;

use super::normals::NetInputs;
use super::tensors::{vectors_from_tensor, vectors_tensor};
use super::{PipelineError, Traversability};
use crate::geometry::{is_valid_point, Grid, Mounting, PointMap, Vec3};
use crate::model::Models;

/// The centroid net's centroids for `normals` (`normals_t` is scratch space).
///
/// # Errors
///
/// [`PipelineError::Model`] when the net fails.
pub fn net_centroids(
    models: &mut Models,
    net: &NetInputs<'_>,
    points: &PointMap,
    normals: &Grid<Vec3>,
    normals_t: &mut Array4<f32>,
) -> Result<PointMap, PipelineError> {
    vectors_tensor(normals, normals_t);
    let out = models.centroids(
        net.rgb.view(),
        net.points_m.view(),
        net.valid.view(),
        normals_t.view(),
    )?;
    Ok(vectors_from_tensor(&out, points, false))
}

/// Eq. 1 at every pixel into `out` (same size): `|n·(p − c)|`, NaN where the point, the normal
/// or the centroid is missing. Rows in parallel.
///
/// ```
/// use tre::geometry::{Grid, Vec3};
/// use tre::pipeline::centroid::roughness_into;
/// let points = Grid::new(2, 1, Vec3::new(0.0, 0.0, 1.0));
/// let normals = Grid::new(2, 1, Vec3::new(0.0, 0.0, -1.0));
/// let centroids = Grid::new(2, 1, Vec3::new(0.5, 0.0, 1.02));
/// let mut r = Grid::new(2, 1, 0.0);
/// roughness_into(&points, &normals, &centroids, &mut r);
/// assert!((r[(1, 0)] - 0.02).abs() < 1e-12);
/// ```
pub fn roughness_into(
    points: &PointMap,
    normals: &Grid<Vec3>,
    centroids: &PointMap,
    out: &mut Grid<f64>,
) {
    let w = out.width().max(1);
    out.as_mut_slice()
        .par_chunks_mut(w)
        .enumerate()
        .for_each(|(y, row)| {
            for (x, r) in row.iter_mut().enumerate() {
                let p = points[(x, y)];
                *r = if is_valid_point(&p) {
                    normals[(x, y)].dot(&(p - centroids[(x, y)])).abs()
                } else {
                    f64::NAN
                };
            }
        });
}

/// Slope of every normal in the gravity frame, radians (NaN: none).
pub fn slopes(normals: &Grid<Vec3>, mounting: &Mounting) -> Grid<f64> {
    let (w, h) = normals.size();
    Grid::par_from_fn(w, h, |x, y| mounting.slope_rad(&normals[(x, y)]))
}

/// Traversable pixels: roughness and (when given) slope within the thresholds; NaN fails.
pub fn traversable(
    roughness_m: &Grid<f64>,
    slope_rad: Option<&Grid<f64>>,
    limits: &Traversability,
) -> Grid<bool> {
    let (w, h) = roughness_m.size();
    Grid::par_from_fn(w, h, |x, y| {
        let flat_enough = slope_rad.is_none_or(|s| s[(x, y)] <= limits.max_slope_rad);
        roughness_m[(x, y)] <= limits.max_roughness_m && flat_enough
    })
}
