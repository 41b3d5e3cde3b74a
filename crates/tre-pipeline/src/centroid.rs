//! Fig. 5, last stages: the local-plane centroid (centroid net, or the window mean) and
//! roughness by Eq. 1, `r = |n·(p − c)|`, with slope and traversability from the normals.

use ndarray::Array4;

use super::normals::NetInputs;
use super::tensors::{vectors_from_tensor_into, vectors_tensor};
use super::{PipelineError, Traversability};
use tre_core::geometry::slope_from_up;
use tre_core::geometry::{Grid, PointMap, Vec3};
use tre_model::Models;

/// The centroid net's centroids for `normals`, written into `out` (`normals_t` is scratch
/// space).
///
/// # Errors
///
/// [`PipelineError::Model`] when the net fails.
pub(crate) fn net_centroids(
    models: &mut Models,
    net: &NetInputs<'_>,
    points: &PointMap,
    normals: &Grid<Vec3>,
    normals_t: &mut Array4<f32>,
    mut out: PointMap,
) -> Result<PointMap, PipelineError> {
    vectors_tensor(normals, normals_t);
    let inputs = [
        net.rgb.view(),
        net.points_m.view(),
        net.valid.view(),
        normals_t.view(),
    ];
    models.centroids_with(inputs, |c| {
        vectors_from_tensor_into(c, points, false, &mut out)
    })?;
    Ok(out)
}

/// Slope of every normal in the gravity frame whose up axis is `up_in_cam` (a unit vector in
/// the camera frame, [`Mounting::up_in_cam`](tre_core::geometry::Mounting::up_in_cam)), radians
/// (NaN: none).
pub(crate) fn slopes(normals: &Grid<Vec3>, up_in_cam: &Vec3) -> Grid<f64> {
    let (w, h) = normals.size();
    Grid::par_from_fn(w, h, |x, y| slope_from_up(up_in_cam, &normals[(x, y)]))
}

/// Traversable pixels: roughness and (when normals and gravity's up axis in the camera frame
/// are given) slope within the thresholds; NaN fails. The slope test is done on cosines,
/// `|up·n| / |n| ≥ cos(max_slope)`, which is `slope ≤ max_slope` without an `acos` per pixel.
pub(crate) fn traversable(
    roughness_m: &Grid<f64>,
    normals_up: Option<(&Grid<Vec3>, &Vec3)>,
    limits: &Traversability,
) -> Grid<bool> {
    let (w, h) = roughness_m.size();
    let max = limits.max_slope_rad;
    let min_cos = if max >= std::f64::consts::FRAC_PI_2 {
        0.0
    } else if max >= 0.0 {
        max.cos()
    } else {
        f64::INFINITY
    };
    Grid::par_from_fn(w, h, |x, y| {
        let flat_enough = normals_up.is_none_or(|(normals, up)| {
            let n = normals[(x, y)];
            up.dot(&n).abs() >= min_cos * n.norm()
        });
        roughness_m[(x, y)] <= limits.max_roughness_m && flat_enough
    })
}

#[cfg(test)]
mod tests {
    use super::traversable;
    use crate::Traversability;
    use tre_core::geometry::{Grid, Mounting, Vec3};

    #[test]
    fn a_wall_is_too_steep_and_the_floor_is_not() {
        let up = Mounting::default().up_in_cam();
        let normals = Grid::from_fn(2, 1, |x, _| {
            if x == 0 {
                -up
            } else {
                Vec3::new(1.0, 0.0, 0.0)
            }
        });
        let rough = Grid::new(2, 1, 0.01);
        let ok = traversable(&rough, Some((&normals, &up)), &Traversability::default());
        assert_eq!(ok.as_slice(), &[true, false]);
    }
}
