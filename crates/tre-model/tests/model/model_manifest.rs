//! The manifest check refuses a model whose file, opset or tensor names disagree with
//! `manifest.json`, naming the model and the field; the shipped manifest loads.

use std::error::Error;
use std::path::Path;

use super::{cfg, models_dir};
use tre_model::{Manifest, ModelError, Models};

type TestResult = Result<(), Box<dyn Error>>;

/// A temporary copy of `models/` whose manifest `edit` has changed.
fn edited_copy(edit: impl FnOnce(&mut Manifest)) -> Result<tempfile::TempDir, Box<dyn Error>> {
    let dir = tempfile::tempdir()?;
    let mut manifest = Manifest::read(&models_dir())?;
    for entry in manifest.models.values() {
        std::fs::copy(models_dir().join(&entry.file), dir.path().join(&entry.file))?;
    }
    edit(&mut manifest);
    std::fs::write(
        dir.path().join("manifest.json"),
        serde_json::to_string_pretty(&manifest)?,
    )?;
    Ok(dir)
}

/// Loads the edited copy and expects a mismatch of `model`'s `field`.
fn expect_mismatch(dir: &Path, model: &str, field: &str) {
    let err = Models::load(dir, &cfg()).expect_err("a mismatch must be refused");
    let message = err.to_string();
    assert!(
        matches!(&err, ModelError::Mismatch { model: m, field: f, .. } if m == model && f == field),
        "{err:?}"
    );
    assert!(
        message.contains(model) && message.contains(field),
        "{message}"
    );
}

#[test]
fn the_shipped_models_load() -> TestResult {
    let models = Models::load(&models_dir(), &cfg())?;
    assert_eq!(models.stride(), models.manifest().stride);
    assert!(models.has_end_to_end());
    Ok(())
}

#[test]
fn a_wrong_sha256_is_refused() -> TestResult {
    let dir = edited_copy(|m| {
        if let Some(e) = m.models.get_mut("normal_refiner") {
            e.sha256 = "0".repeat(64);
        }
    })?;
    expect_mismatch(dir.path(), "normal_refiner", "sha256");
    Ok(())
}

#[test]
fn a_wrong_input_name_is_refused() -> TestResult {
    let dir = edited_copy(|m| {
        if let Some(e) = m.models.get_mut("centroid_net") {
            e.inputs[1].name = "points".to_owned();
        }
    })?;
    expect_mismatch(dir.path(), "centroid_net", "inputs[1].name");
    Ok(())
}

#[test]
fn a_wrong_opset_is_refused() -> TestResult {
    let dir = edited_copy(|m| {
        if let Some(e) = m.models.get_mut("depth_net") {
            e.opset -= 1;
        }
    })?;
    expect_mismatch(dir.path(), "depth_net", "opset");
    Ok(())
}

#[test]
fn a_wrong_channel_count_is_refused() -> TestResult {
    let dir = edited_copy(|m| {
        if let Some(e) = m.models.get_mut("neighbour_net") {
            e.outputs[0].shape[1] = tre_model::Dim::Fixed(48);
        }
    })?;
    expect_mismatch(dir.path(), "neighbour_net", "outputs[0].channels");
    Ok(())
}

#[test]
fn a_missing_file_and_a_missing_stage_are_named() -> TestResult {
    let dir = edited_copy(|_| {})?;
    std::fs::remove_file(dir.path().join("centroid_net.onnx"))?;
    let err = Models::load(dir.path(), &cfg()).expect_err("the file is gone");
    assert!(
        matches!(&err, ModelError::MissingFile { model, .. } if model == "centroid_net"),
        "{err:?}"
    );
    let dir = edited_copy(|m| {
        m.models.remove("depth_net");
    })?;
    let err = Models::load(dir.path(), &cfg()).expect_err("depth_net is required");
    assert!(err.to_string().contains("depth_net"), "{err}");
    Ok(())
}

#[test]
fn a_manifest_without_the_end_to_end_baseline_loads() -> TestResult {
    let dir = edited_copy(|m| {
        m.models.remove("end_to_end");
    })?;
    let models = Models::load(dir.path(), &cfg())?;
    assert!(!models.has_end_to_end());
    Ok(())
}
