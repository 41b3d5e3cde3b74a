//! `tre eval` on a generated split: the geometric baseline's scores, and sensor depth against
//! the exact ground truth.

use super::*;

#[test]
fn eval_scores_the_geometric_baseline_on_a_generated_split() {
    let dir = tempfile::tempdir().unwrap();
    let cfg = SynthConfig {
        out: dir.path().to_owned(),
        scenes: 3,
        seed: 11,
        size: (96, 96),
        views: 2,
        ply: false,
        test_fraction: 0.5,
        ..SynthConfig::default()
    };
    let m = tre::synth::generate(&cfg).unwrap();
    let split = if m.counts.1 > 0 { "test" } else { "train" };
    let out = std::process::Command::new(env!("CARGO_BIN_EXE_tre"))
        .args([
            "eval",
            "--data",
            dir.path().to_str().unwrap(),
            "--mode",
            "geometric",
            "--split",
            split,
        ])
        .output()
        .unwrap();
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    // RMSE is a finite, positive number of centimetres, below a metre on ground seen from 1 m.
    let rmse: f64 = text
        .split("RMSE ")
        .nth(1)
        .unwrap()
        .split(' ')
        .next()
        .unwrap()
        .parse()
        .unwrap();
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
    let out = std::process::Command::new(env!("CARGO_BIN_EXE_tre"))
        .args([
            "eval",
            "--data",
            data.to_str().unwrap(),
            "--mode",
            "geometric",
        ])
        .args(["--split", split, "--depth-source", source])
        .output()
        .unwrap();
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    text.split("RMSE ")
        .nth(1)
        .unwrap()
        .split(' ')
        .next()
        .unwrap()
        .parse()
        .unwrap()
}

#[test]
fn eval_reads_sensor_depth_against_exact_ground_truth() {
    let dir = tempfile::tempdir().unwrap();
    let cfg = SynthConfig {
        out: dir.path().to_owned(),
        scenes: 2,
        seed: 4,
        size: (128, 96),
        views: 2,
        ply: false,
        test_fraction: 0.0,
        sensors: vec![SensorPreset::KinectV1],
        ..SynthConfig::default()
    };
    tre::synth::generate(&cfg).unwrap();
    let exact = eval_rmse(dir.path(), "train", "exact");
    let sensor = eval_rmse(dir.path(), "train", "sensor");
    // Kinect noise and holes make the spec on sensor depth differ more from the exact truth.
    assert!(
        sensor > exact + 0.05,
        "exact {exact} cm, sensor {sensor} cm"
    );
}
