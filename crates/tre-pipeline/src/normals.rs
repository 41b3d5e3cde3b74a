//! Fig. 5, normals: least-squares planes, or the neighbour net's 7×7 probabilities turned into
//! DSAC plane hypotheses (seeded per request); then, optionally, the normal refiner.

use ndarray::Array4;

use super::tensors::{vectors_from_tensor_into, vectors_tensor};
use super::PipelineError;
use tre_core::geometry::dsac::{dsac_normals_into, DsacScratch};
use tre_core::geometry::normals::{local_planes_into, PackedPoints};
use tre_core::geometry::{
    dsac::DsacConfig,
    normals::{LocalPlanes, Neighbourhood},
    Grid, PointMap, Vec3,
};
use tre_model::Models;

/// Initial normals and, for LS, the window centroids that came with them for free.
pub(crate) struct InitialNormals {
    /// Unit normals facing the camera (NaN: none).
    pub(crate) normals: Grid<Vec3>,
    /// Window centroids, when the LS fit computed them.
    pub(crate) window_centroids: Option<PointMap>,
}

/// The network inputs shared by the later stages, at the working size.
pub(crate) struct NetInputs<'a> {
    /// RGB, `1 × 3 × H × W` in [0, 1].
    pub(crate) rgb: &'a Array4<f32>,
    /// Points, `1 × 3 × H × W` metres, 0 where invalid.
    pub(crate) points_m: &'a Array4<f32>,
    /// Validity, `1 × 1 × H × W`.
    pub(crate) valid: &'a Array4<f32>,
}

/// LS normals and window centroids over `hood` (focal `fx_px` at the working size), written
/// into `planes`' grids with `packed` as scratch (all reused across frames).
pub(crate) fn ls_normals(
    points: &PointMap,
    fx_px: f64,
    hood: &Neighbourhood,
    packed: &mut PackedPoints,
    mut planes: LocalPlanes,
) -> InitialNormals {
    local_planes_into(points, fx_px, hood, packed, &mut planes);
    InitialNormals {
        normals: planes.normal,
        window_centroids: Some(planes.centroid),
    }
}

/// DSAC normals: the neighbour net's logits, then [`dsac_normals_into`] with `cfg` (the
/// request's seed and hypotheses), written into `out` with `scratch` (both reused across
/// frames).
///
/// # Errors
///
/// [`PipelineError::Model`] when the net fails, [`PipelineError::Geometry`] when its logits do
/// not fit the point map.
pub(crate) fn dsac_normals_from_net(
    models: &mut Models,
    net: &NetInputs<'_>,
    points: &PointMap,
    cfg: &DsacConfig,
    scratch: &mut DsacScratch,
    mut out: Grid<Vec3>,
) -> Result<InitialNormals, PipelineError> {
    models.neighbour_logits_with(
        net.rgb.view(),
        net.points_m.view(),
        net.valid.view(),
        |logits| match logits.as_slice() {
            Some(logits) => dsac_normals_into(points, logits, cfg, scratch, &mut out),
            None => {
                let logits = logits.iter().copied().collect::<Vec<_>>();
                dsac_normals_into(points, &logits, cfg, scratch, &mut out)
            }
        },
    )??;
    Ok(InitialNormals {
        normals: out,
        window_centroids: None,
    })
}

/// The refiner's unit normals from the initial ones, written into `out` (`normals_t` is
/// scratch space).
///
/// # Errors
///
/// [`PipelineError::Model`] when the net fails.
pub(crate) fn refine(
    models: &mut Models,
    net: &NetInputs<'_>,
    points: &PointMap,
    initial: &Grid<Vec3>,
    normals_t: &mut Array4<f32>,
    mut out: Grid<Vec3>,
) -> Result<Grid<Vec3>, PipelineError> {
    vectors_tensor(initial, normals_t);
    let inputs = [
        net.rgb.view(),
        net.points_m.view(),
        net.valid.view(),
        normals_t.view(),
    ];
    models.refine_normals_with(inputs, |n| {
        vectors_from_tensor_into(n, points, true, &mut out)
    })?;
    Ok(out)
}
