//! Fig. 5, normals: least-squares planes, or the neighbour net's 7×7 probabilities turned into
//! DSAC plane hypotheses (seeded per request); then, optionally, the normal refiner.

use ndarray::Array4;

use super::tensors::{vectors_from_tensor, vectors_tensor};
use super::PipelineError;
use crate::geometry::{
    dsac_normals, local_planes, DsacConfig, Grid, Neighbourhood, PointMap, Vec3,
};
use crate::model::Models;

/// Initial normals and, for LS, the window centroids that came with them for free.
pub struct InitialNormals {
    /// Unit normals facing the camera (NaN: none).
    pub normals: Grid<Vec3>,
    /// Window centroids, when the LS fit computed them.
    pub window_centroids: Option<PointMap>,
}

/// The network inputs shared by the later stages, at the working size.
pub struct NetInputs<'a> {
    /// RGB, `1 × 3 × H × W` in [0, 1].
    pub rgb: &'a Array4<f32>,
    /// Points, `1 × 3 × H × W` metres, 0 where invalid.
    pub points_m: &'a Array4<f32>,
    /// Validity, `1 × 1 × H × W`.
    pub valid: &'a Array4<f32>,
}

/// LS normals and window centroids over `hood` (focal `fx_px` at the working size).
pub fn ls_normals(points: &PointMap, fx_px: f64, hood: &Neighbourhood) -> InitialNormals {
    let planes = local_planes(points, fx_px, hood);
    InitialNormals {
        normals: planes.normal,
        window_centroids: Some(planes.centroid),
    }
}

/// DSAC normals: the neighbour net's logits, then [`dsac_normals`] with the request's `seed`.
///
/// # Errors
///
/// [`PipelineError::Model`] when the net fails, [`PipelineError::Geometry`] when its logits do
/// not fit the point map.
pub fn dsac_normals_from_net(
    models: &mut Models,
    net: &NetInputs<'_>,
    points: &PointMap,
    seed: u64,
) -> Result<InitialNormals, PipelineError> {
    let cfg = DsacConfig {
        seed,
        ..DsacConfig::default()
    };
    let normals = models.neighbour_logits_with(
        net.rgb.view(),
        net.points_m.view(),
        net.valid.view(),
        |logits| match logits.as_slice() {
            Some(logits) => dsac_normals(points, logits, &cfg),
            None => dsac_normals(points, &logits.iter().copied().collect::<Vec<_>>(), &cfg),
        },
    )??;
    Ok(InitialNormals {
        normals,
        window_centroids: None,
    })
}

/// The refiner's unit normals from the initial ones (`normals_t` is scratch space).
///
/// # Errors
///
/// [`PipelineError::Model`] when the net fails.
pub fn refine(
    models: &mut Models,
    net: &NetInputs<'_>,
    points: &PointMap,
    initial: &Grid<Vec3>,
    normals_t: &mut Array4<f32>,
) -> Result<Grid<Vec3>, PipelineError> {
    vectors_tensor(initial, normals_t);
    let inputs = [
        net.rgb.view(),
        net.points_m.view(),
        net.valid.view(),
        normals_t.view(),
    ];
    Ok(models.refine_normals_with(inputs, |n| vectors_from_tensor(n, points, true))?)
}
