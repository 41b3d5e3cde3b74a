//! `tre eval` on a generated split: the geometric baseline's scores, and sensor depth against
//! the exact ground truth.

use super::*;

#[test]
fn eval_scores_the_geometric_baseline_on_a_generated_split() {
    let dir = tempfile::tempdir().unwrap();
    let cfg = SynthConfig {
        ply: false,
        test_fraction: 0.5,
        ..synth_config(dir.path(), 3, 11, (96, 96), 2)
    };
    let m = tre::synth::dataset::generate(&cfg).unwrap();
    let split = if m.counts.1 > 0 { "test" } else { "train" };
    let (rmse, text) = eval_geometric(dir.path(), split, &[]);
    // RMSE is a finite, positive number of centimetres, below a metre on ground seen from 1 m.
    assert!(rmse > 0.0 && rmse < 100.0, "{text}");
    assert!(text.contains("normals    mean"), "{text}");
    // A split with no frames is a clear error.
    let bad = std::process::Command::new(env!("CARGO_BIN_EXE_tre"))
        .args([
            "eval",
            "--data",
            dir.path().to_str().unwrap(),
            "--split",
            "nope",
        ])
        .output()
        .unwrap();
    assert!(
        !bad.status.success()
            && String::from_utf8_lossy(&bad.stderr).contains("no frames in split")
    );
}

/// RMSE (cm) printed by `tre eval --mode geometric` on `data`'s split with `--depth-source`.
fn eval_rmse(data: &Path, split: &str, source: &str) -> f64 {
    eval_geometric(data, split, &["--depth-source", source]).0
}

/// `tre eval --mode geometric` on `data`'s split with `args`: the RMSE (cm) it printed and its
/// output.
fn eval_geometric(data: &Path, split: &str, args: &[&str]) -> (f64, String) {
    let out = std::process::Command::new(env!("CARGO_BIN_EXE_tre"))
        .args([
            "eval",
            "--data",
            data.to_str().unwrap(),
            "--mode",
            "geometric",
            "--geometric",
            "spec",
        ])
        .args(["--split", split])
        .args(args)
        .output()
        .unwrap();
    let text = String::from_utf8_lossy(&out.stdout).into_owned();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let rmse = text
        .split("RMSE ")
        .nth(1)
        .unwrap()
        .split(' ')
        .next()
        .unwrap()
        .parse()
        .unwrap();
    (rmse, text)
}

#[test]
fn eval_reads_sensor_depth_against_exact_ground_truth() {
    let dir = tempfile::tempdir().unwrap();
    let cfg = SynthConfig {
        ply: false,
        test_fraction: 0.0,
        sensors: vec![SensorPreset::KinectV1],
        ..synth_config(dir.path(), 2, 4, (128, 96), 2)
    };
    tre::synth::dataset::generate(&cfg).unwrap();
    let exact = eval_rmse(dir.path(), "train", "exact");
    let sensor = eval_rmse(dir.path(), "train", "sensor");
    // Kinect noise and holes make the spec on sensor depth differ more from the exact truth.
    assert!(
        sensor > exact + 0.05,
        "exact {exact} cm, sensor {sensor} cm"
    );
}
