//! Every model in `models/manifest.json` against the PyTorch outputs the export wrote beside its
//! inputs (`tests/fixtures/onnx_parity/<model>/{input,output}_<name>.npy`, 1×C×32×48 float32):
//! `max |ort − torch| / max(1, |torch|) ≤ 1e-4` per element. (The flat-ground prior depth
//! beside them: `crates/tre-pipeline/tests/prior_depth.rs`.)

use std::error::Error;
use std::path::{Path, PathBuf};

use ndarray::{Array4, ArrayView4};
use tre_model::{Manifest, ModelSession, SessionConfig};

/// Largest allowed error, relative to max(1, |torch|).
const TOLERANCE: f64 = 1e-4;

/// The repository's root, two folders above this crate.
fn root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../..")
}

/// A 4-D float `.npy` as an array.
fn read4(path: &Path) -> Result<Array4<f32>, Box<dyn Error>> {
    let a = tre_io::npy::read_npy(std::fs::File::open(path)?)?;
    let [n, c, h, w] = a.shape[..] else {
        return Err(format!("{}: shape {:?} is not 4-D", path.display(), a.shape).into());
    };
    let data = a.data.iter().map(|&v| v as f32).collect();
    Ok(Array4::from_shape_vec((n, c, h, w), data)?)
}

#[test]
fn every_manifest_model_matches_pytorch() -> Result<(), Box<dyn Error>> {
    let models = root().join("models");
    let manifest = Manifest::read(&models)?;
    let cfg = SessionConfig {
        intra_threads: 1,
        ..SessionConfig::default()
    };
    assert!(manifest.models.len() >= 4);
    for (name, entry) in &manifest.models {
        let fixtures = root().join("tests/fixtures/onnx_parity").join(name);
        let mut session = ModelSession::load(&models, name, entry, manifest.stride, &cfg)?;
        let inputs = entry
            .inputs
            .iter()
            .map(|t| read4(&fixtures.join(format!("input_{}.npy", t.name))))
            .collect::<Result<Vec<_>, _>>()?;
        let views: Vec<ArrayView4<'_, f32>> = inputs.iter().map(|a| a.view()).collect();
        let got = session.run(&views)?;
        let want = read4(&fixtures.join(format!("output_{}.npy", entry.outputs[0].name)))?;
        assert_eq!(got.dim(), want.dim(), "{name}");
        let worst = got
            .iter()
            .zip(want.iter())
            .map(|(&g, &w)| f64::from(g - w).abs() / f64::from(w).abs().max(1.0))
            .fold(0.0, f64::max);
        assert!(worst <= TOLERANCE, "{name}: relative error {worst:e}");
    }
    Ok(())
}
