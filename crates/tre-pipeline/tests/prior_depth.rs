//! The flat-ground prior depth fed to the depth net and the end-to-end baseline
//! (`tre_pipeline::prior_depth`) against the training code's `geometry.prior_depth`; the models
//! themselves against PyTorch: `crates/tre-model/tests/model/onnx_parity.rs`.

use std::error::Error;
use std::path::Path;

/// The flat-ground prior depth fed to the depth net and the end-to-end baseline, against the
/// training code's `geometry.prior_depth` (`tests/fixtures/onnx_parity/prior_depth.json`, float32
/// values rounded to 1e-6): within 1e-5 relative.
#[test]
fn prior_depth_matches_the_training_code() -> Result<(), Box<dyn Error>> {
    let text = std::fs::read_to_string(
        Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("../../tests/fixtures/onnx_parity/prior_depth.json"),
    )?;
    let doc: serde_json::Value = serde_json::from_str(&text)?;
    let cases = doc["cases"].as_array().ok_or("no cases")?;
    assert_eq!(cases.len(), 2);
    let mut above_horizon = 0;
    for case in cases {
        let k: Vec<f64> = serde_json::from_value(case["intrinsics"].clone())?;
        let intr = tre_core::geometry::Intrinsics::new(k[0], k[1], k[2], k[3])?;
        let mounting = tre_core::geometry::Mounting::new(
            case["pitch_rad"].as_f64().ok_or("pitch")?,
            case["height_m"].as_f64().ok_or("height")?,
        )?;
        let (w, h) = (
            case["width"].as_u64().ok_or("width")? as usize,
            case["height"].as_u64().ok_or("height")? as usize,
        );
        let expected: Vec<f64> = serde_json::from_value(case["prior_depth_m"].clone())?;
        let got = tre_pipeline::prior_depth(&intr, &mounting, w, h);
        for y in 0..h {
            for x in 0..w {
                let (e, g) = (expected[y * w + x], got[(x, y)]);
                assert!(
                    (e - g).abs() <= 1e-5 * e.abs().max(1.0),
                    "({x}, {y}): python {e}, rust {g}"
                );
                above_horizon += usize::from(e == tre_pipeline::MAX_PRIOR_DEPTH_M);
            }
        }
    }
    // The second camera looks above the horizon: those rows take the 20 m cap on both sides.
    assert!(above_horizon > 0);
    Ok(())
}
