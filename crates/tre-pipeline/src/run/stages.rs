//! The normal and centroid stages of one frame ([`Stages`]): LS normals or the neighbour net and
//! DSAC, the refiner, and window or net centroids, each writing into the pipeline's buffers.

use ndarray::Array4;

use super::Scratch;
use crate::centroid::net_centroids;
use crate::normals::{dsac_normals_from_net, ls_normals, refine, InitialNormals, NetInputs};
use crate::spares::Spares;
use crate::{NormalsMethod, PipelineConfig, PipelineError};
use tre_core::geometry::dsac::{DsacConfig, DsacScratch};
use tre_core::geometry::normals::{window_centroids_into, LocalPlanes, PackedPoints};
use tre_core::geometry::{Grid, PointMap, Vec3};
use tre_model::Models;

/// The normal and centroid stages of one frame: the models, the network inputs and the buffers
/// they write into, borrowed from the pipeline.
pub(super) struct Stages<'a> {
    models: &'a mut Option<Models>,
    net: NetInputs<'a>,
    points: &'a PointMap,
    normals_t: &'a mut Array4<f32>,
    packed: &'a mut PackedPoints,
    dsac: &'a mut DsacScratch,
    spares: &'a mut Spares,
}

impl<'a> Stages<'a> {
    pub(super) fn new(
        models: &'a mut Option<Models>,
        scratch: &'a mut Scratch,
        points: &'a PointMap,
    ) -> Self {
        let Scratch {
            rgb,
            points: points_m,
            valid,
            normals,
            packed,
            dsac,
            spares,
            ..
        } = scratch;
        Self {
            models,
            net: NetInputs {
                rgb,
                points_m,
                valid,
            },
            points,
            normals_t: normals,
            packed,
            dsac,
            spares,
        }
    }

    /// LS normals (with their window centroids) or the neighbour net and DSAC.
    pub(super) fn initial_normals(
        &mut self,
        method: NormalsMethod,
        fx_px: f64,
        cfg: &PipelineConfig,
    ) -> Result<InitialNormals, PipelineError> {
        Ok(match method {
            NormalsMethod::Ls => {
                let planes = LocalPlanes {
                    centroid: self.spares.take(),
                    normal: self.spares.take(),
                };
                let hood = &cfg.neighbourhood;
                ls_normals(self.points, fx_px, hood, self.packed, planes)
            }
            NormalsMethod::Dsac => {
                let (models, out) = (loaded(self.models)?, self.spares.take());
                let (net, points) = (&self.net, self.points);
                let dsac = DsacConfig {
                    hypotheses: cfg.dsac_hypotheses,
                    seed: cfg.seed,
                    ..DsacConfig::default()
                };
                dsac_normals_from_net(models, net, points, &dsac, self.dsac, out)?
            }
        })
    }

    /// The refiner's normals from `initial`, whose buffer goes back to the spares.
    pub(super) fn refined(&mut self, initial: Grid<Vec3>) -> Result<Grid<Vec3>, PipelineError> {
        let (out, models) = (self.spares.take(), loaded(self.models)?);
        let refined = refine(
            models,
            &self.net,
            self.points,
            &initial,
            self.normals_t,
            out,
        )?;
        self.spares.keep(initial);
        Ok(refined)
    }

    /// Window centroids computed alone (normals from DSAC).
    pub(super) fn window_centroids(&mut self, fx_px: f64, cfg: &PipelineConfig) -> PointMap {
        let mut out = self.spares.take();
        let hood = &cfg.neighbourhood;
        window_centroids_into(self.points, fx_px, hood, self.packed, &mut out);
        out
    }

    /// The centroid net's centroids for `normals`; `unused` (the LS window centroids, if any)
    /// goes back to the spares.
    pub(super) fn net_centroids(
        &mut self,
        normals: &Grid<Vec3>,
        unused: Option<PointMap>,
    ) -> Result<PointMap, PipelineError> {
        if let Some(c) = unused {
            self.spares.keep(c);
        }
        let (out, models) = (self.spares.take(), loaded(self.models)?);
        net_centroids(models, &self.net, self.points, normals, self.normals_t, out)
    }
}

/// The models, or the error that says they are needed (checked up front; kept for safety).
pub(super) fn loaded(models: &mut Option<Models>) -> Result<&mut Models, PipelineError> {
    models
        .as_mut()
        .ok_or_else(|| PipelineError::ModelsRequired {
            label: "this configuration".to_owned(),
            networks: Vec::new(),
            loaded: false,
        })
}
