//! Every model in `models/manifest.json` against the PyTorch outputs the export wrote beside its
//! inputs (`tests/fixtures/onnx_parity/<model>/{input,output}_<name>.npy`, 1×C×32×48 float32):
//! `max |ort − torch| / max(1, |torch|) ≤ 1e-4` per element.

use std::error::Error;
use std::path::{Path, PathBuf};

use ndarray::{Array4, ArrayView4};
use tre::model::{Manifest, ModelSession, SessionConfig};

/// Largest allowed error, relative to max(1, |torch|).
const TOLERANCE: f64 = 1e-4;

fn root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).to_path_buf()
}

/// A 4-D float `.npy` as an array.
fn read4(path: &Path) -> Result<Array4<f32>, Box<dyn Error>> {
    let a = tre::io::npy::read_npy(std::fs::File::open(path)?)?;
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

/// The flat-ground prior depth fed to the depth net and the end-to-end baseline, against the
/// training code's `geometry.prior_depth` (`tests/fixtures/onnx_parity/prior_depth.json`, float32
/// values rounded to 1e-6): within 1e-5 relative.
#[test]
fn prior_depth_matches_the_training_code() -> Result<(), Box<dyn Error>> {
    let text = std::fs::read_to_string(root().join("tests/fixtures/onnx_parity/prior_depth.json"))?;
    let doc: serde_json::Value = serde_json::from_str(&text)?;
    let cases = doc["cases"].as_array().ok_or("no cases")?;
    assert_eq!(cases.len(), 2);
    let mut above_horizon = 0;
    for case in cases {
        let k: Vec<f64> = serde_json::from_value(case["intrinsics"].clone())?;
        let intr = tre::geometry::Intrinsics::new(k[0], k[1], k[2], k[3])?;
        let mounting = tre::geometry::Mounting::new(
            case["pitch_rad"].as_f64().ok_or("pitch")?,
            case["height_m"].as_f64().ok_or("height")?,
        )?;
        let (w, h) = (
            case["width"].as_u64().ok_or("width")? as usize,
            case["height"].as_u64().ok_or("height")? as usize,
        );
        let expected: Vec<f64> = serde_json::from_value(case["prior_depth_m"].clone())?;
        let got = tre::pipeline::prior_depth(&intr, &mounting, w, h);
        for y in 0..h {
            for x in 0..w {
                let (e, g) = (expected[y * w + x], got[(x, y)]);
                assert!(
                    (e - g).abs() <= 1e-5 * e.abs().max(1.0),
                    "({x}, {y}): python {e}, rust {g}"
                );
                above_horizon += usize::from(e == tre::pipeline::MAX_PRIOR_DEPTH_M);
            }
        }
    }
    // The second camera looks above the horizon: those rows take the 20 m cap on both sides.
    assert!(above_horizon > 0);
    Ok(())
}
