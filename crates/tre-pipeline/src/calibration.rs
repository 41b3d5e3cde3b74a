//! Reading the calibrated roughness intervals (`uncertainty.json` beside the models'
//! manifest; docs/uncertainty.md).

use std::path::Path;

use super::PipelineError;
use tre_core::roughness::interval::{Calibration, CALIBRATION_FILE};
use tre_model::Manifest;

/// The models of a manifest by name and hash, as a calibration records them
/// ([`Calibration::models`]), so that tables fitted on other models are told apart.
pub fn models_key(manifest: &Manifest) -> String {
    manifest
        .models
        .iter()
        .map(|(name, e)| format!("{name}:{}", &e.sha256[..12.min(e.sha256.len())]))
        .collect::<Vec<_>>()
        .join(",")
}

/// Why `cal` should be fitted again for the models of `manifest`, if it should: it names other
/// models (a model changed since `tre calibrate` ran).
pub fn stale_calibration(cal: &Calibration, manifest: &Manifest) -> Option<String> {
    let key = models_key(manifest);
    (cal.models != key).then(|| {
        format!(
            "the intervals of {CALIBRATION_FILE} were fitted on other models ({} against {key}); \
             run `tre calibrate` again",
            cal.models
        )
    })
}

/// The calibration in the models folder `dir`, `None` when it has no `uncertainty.json`.
///
/// # Errors
///
/// [`PipelineError::Calibration`] when the file exists but does not read or parse, or has
/// another format than 1.
pub fn read_calibration(dir: &Path) -> Result<Option<Calibration>, PipelineError> {
    let path = dir.join(CALIBRATION_FILE);
    let fail = |reason| PipelineError::Calibration {
        path: path.clone(),
        reason,
    };
    let text = match std::fs::read_to_string(&path) {
        Ok(t) => t,
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok(None),
        Err(e) => return Err(fail(CalibrationProblem::Read(e))),
    };
    let cal: Calibration =
        serde_json::from_str(&text).map_err(|e| fail(CalibrationProblem::Json(e)))?;
    if cal.format != 1 {
        return Err(fail(CalibrationProblem::Format(cal.format)));
    }
    for (mode, t) in &cal.tables {
        let cells =
            tre_core::roughness::interval::READING_EDGES_M.len() * t.second_axis.edges().len();
        if [t.lo_m.len(), t.hi_m.len(), t.samples.len(), t.own.len()] != [cells; 4] {
            return Err(fail(CalibrationProblem::Bins {
                mode: mode.clone(),
                cells,
            }));
        }
    }
    Ok(Some(cal))
}

/// Why a calibration file does not read ([`PipelineError::Calibration`]).
#[derive(Debug, thiserror::Error)]
pub enum CalibrationProblem {
    /// The file exists but cannot be read.
    #[error(transparent)]
    Read(std::io::Error),
    /// The file is not a calibration's JSON.
    #[error(transparent)]
    Json(serde_json::Error),
    /// Another format than 1.
    #[error("format {0} (this build reads 1)")]
    Format(u32),
    /// A mode's table with another number of bins than the edges make.
    #[error("table {mode:?} does not have {cells} bins")]
    Bins {
        /// The table's mode.
        mode: String,
        /// The bins the edges make.
        cells: usize,
    },
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_missing_file_is_none_and_a_bad_one_an_error() {
        let dir = tempfile::tempdir().expect("tempdir");
        assert!(read_calibration(dir.path()).expect("no file").is_none());
        std::fs::write(dir.path().join(CALIBRATION_FILE), "{\"format\": 2}").expect("write");
        let e = read_calibration(dir.path()).expect_err("bad file");
        assert!(
            matches!(
                &e,
                PipelineError::Calibration {
                    reason: CalibrationProblem::Json(_),
                    ..
                }
            ),
            "{e:?}"
        );
        assert!(e.to_string().contains("uncertainty.json"), "{e}");
    }

    #[test]
    fn a_calibration_of_another_format_or_size_says_so() {
        let committed = Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("../../models")
            .join(CALIBRATION_FILE);
        let text = std::fs::read_to_string(committed).expect("committed");
        let good: serde_json::Value = serde_json::from_str(&text).expect("JSON");
        let dir = tempfile::tempdir().expect("tempdir");
        let read = |v: &serde_json::Value| {
            std::fs::write(dir.path().join(CALIBRATION_FILE), v.to_string()).expect("write");
            read_calibration(dir.path()).expect_err("bad file")
        };
        let mut other = good.clone();
        other["format"] = 2.into();
        let e = read(&other);
        assert!(
            matches!(
                &e,
                PipelineError::Calibration {
                    reason: CalibrationProblem::Format(2),
                    ..
                }
            ),
            "{e:?}"
        );
        assert!(
            e.to_string().ends_with("format 2 (this build reads 1)"),
            "{e}"
        );
        let mut short = good;
        short["tables"]["rgb"]["lo_m"] = serde_json::json!([]);
        let e = read(&short);
        assert!(
            matches!(&e, PipelineError::Calibration { reason: CalibrationProblem::Bins { mode, .. }, .. }
                if mode == "rgb"),
            "{e:?}"
        );
        assert!(
            e.to_string().contains("table \"rgb\" does not have "),
            "{e}"
        );
    }

    #[test]
    fn the_committed_calibration_reads() {
        let models = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../models");
        let cal = read_calibration(&models)
            .expect("reads")
            .expect("committed");
        for mode in ["rgb", "rgbd", "geometric"] {
            assert!(cal.table(mode).is_some(), "{mode}");
        }
    }
}
