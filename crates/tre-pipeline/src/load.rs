//! A pipeline for the configurations a command will run: the models loaded only when one of
//! them runs a network, with the calibrated intervals beside them (`tre infer`, `eval`, `map`,
//! `calibrate`).

use std::path::Path;

use tre_model::{check_threads, cores, find_models, locate_models, Models, SessionConfig};

use super::{read_calibration, stale_calibration, Pipeline, PipelineConfig, PipelineError};

impl Pipeline {
    /// A pipeline that can run every one of `configs`: the models of the folder `models` names
    /// (`None`: [`tre_model::locate_models`]'s search) when any of them runs a network, on
    /// sessions of `ort_threads` threads per operator (0: one per core), with the calibration
    /// beside them; without networks, no models, but the calibration of a models folder if one
    /// is found. A calibration made for other models is used with a warning.
    ///
    /// # Errors
    ///
    /// [`PipelineError::Threads`], [`PipelineError::Model`] when no models folder is found,
    /// [`PipelineError::LoadModels`], [`PipelineError::Calibration`].
    pub fn for_configs(
        models: Option<&Path>,
        ort_threads: usize,
        configs: &[PipelineConfig],
    ) -> Result<Self, PipelineError> {
        if configs.iter().all(|c| c.networks().is_empty()) {
            let calibration = match locate_models(models) {
                Ok(found) => read_calibration(&found.dir)?,
                Err(_) => None,
            };
            return Ok(Self::new(None).with_calibration(calibration));
        }
        check_threads(None, ort_threads, cores())?;
        let session = SessionConfig {
            intra_threads: ort_threads,
            ..SessionConfig::default()
        };
        let dir = find_models(models)?;
        let loaded = Models::load(&dir, &session).map_err(|source| PipelineError::LoadModels {
            dir: dir.clone(),
            source: Box::new(source),
        })?;
        let calibration = read_calibration(&dir)?;
        if let Some(stale) = calibration
            .as_ref()
            .and_then(|c| stale_calibration(c, loaded.manifest()))
        {
            tracing::warn!("{}: {stale}", dir.display());
        }
        Ok(Self::new(Some(loaded)).with_calibration(calibration))
    }
}
