//! `tre infer` on the committed sample frame: depth sent with `--mode rgb` refused (not
//! dropped), the JSON record beside the maps, and a three-state map mostly unknown said so on
//! the console, in the previews' titles and in the record.

use super::*;

const SAMPLE: &str = "samples/tum_fr2_desk";

fn sample(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join(SAMPLE)
        .join(name)
}

/// The record `tre infer -o out` wrote beside `out`.
fn record_of(out: &Path) -> serde_json::Value {
    let text = std::fs::read_to_string(out.with_extension("json")).unwrap();
    serde_json::from_str(&text).unwrap()
}

#[test]
fn infer_refuses_depth_in_the_rgb_mode_naming_the_modes_that_use_it() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("r.png");
    let (rgb, depth, camera) = (
        sample("rgb.png"),
        sample("depth.png"),
        sample("camera.json"),
    );
    let args = [
        "infer",
        s(&rgb),
        "--depth",
        s(&depth),
        "--camera",
        s(&camera),
        "--mode",
        "rgb",
        "-o",
        s(&out),
    ];
    let o = tre(&args);
    let err = stderr(&o);
    assert!(!o.status.success(), "{err}");
    assert!(
        err.contains("--mode rgb with --depth")
            && err.contains("rgbd")
            && err.contains("geometric"),
        "{err}"
    );
    assert!(!out.exists(), "nothing is written");
}

/// Runs `tre infer` on the sample in `mode` (rgb: without the depth) into `dir`; returns the
/// output path, what it printed (stderr, then stdout) and the record.
fn infer_sample(dir: &Path, mode: &str) -> (PathBuf, String, serde_json::Value) {
    let out = dir.join(format!("{mode}/roughness.png"));
    let (rgb, depth, camera) = (
        sample("rgb.png"),
        sample("depth.png"),
        sample("camera.json"),
    );
    let mut args = vec!["infer", s(&rgb), "--camera", s(&camera), "--mode", mode];
    if mode != "rgb" {
        args.extend(["--depth", s(&depth)]);
    }
    args.extend(["-o", s(&out)]);
    let o = tre(&args);
    let err = stderr(&o);
    assert!(o.status.success(), "{mode}: {err}");
    let stdout = String::from_utf8_lossy(&o.stdout);
    (out.clone(), format!("{err}\n{stdout}"), record_of(&out))
}

/// What the record says against what ran: the mode and stages, gravity, the assumptions the
/// console warned of, the sensor, the committed models' hashes, timings, and every file.
fn check_record(mode: &str, err: &str, r: &serde_json::Value) {
    assert_eq!(r["mode"], mode);
    assert_eq!(r["mode_asked"], true);
    assert!(!r["stages"].as_str().unwrap().is_empty());
    assert_eq!(r["size"], serde_json::json!([640, 480]));
    let gravity = r["gravity"]["source"].as_str().unwrap();
    assert!(["stated", "estimated", "unknown"].contains(&gravity));
    assert!(err.contains(&format!("gravity: {gravity}")), "{err}");
    for a in r["assumptions"].as_array().unwrap() {
        let words = a["words"].as_str().unwrap();
        assert!(
            err.contains(&format!("warning: {words}")),
            "{words} not warned of"
        );
    }
    assert_eq!(r["sensor"]["noise_model"], "kinect_v1");
    let manifest = tre::model::Manifest::read(Path::new("models")).unwrap();
    assert_eq!(r["models"]["key"], tre::pipeline::models_key(&manifest));
    let stages = r["timings_ms"]["stages"].as_array().unwrap();
    assert!(!stages.is_empty() && r["timings_ms"]["total"].as_f64().unwrap() > 0.0);
    let files = r["files"].as_array().unwrap();
    assert!(files.len() >= 2);
    for f in files {
        let path = Path::new(f["path"].as_str().unwrap());
        assert!(
            path.is_file(),
            "{} recorded but not written",
            path.display()
        );
    }
}

#[test]
fn infer_writes_a_record_and_says_when_its_map_is_mostly_unknown() {
    let dir = tempfile::tempdir().unwrap();
    let mut caveats = Vec::new();
    for mode in ["rgbd", "rgb"] {
        let (_, err, r) = infer_sample(dir.path(), mode);
        check_record(mode, &err, &r);
        let unknown = r["three_state"]["unknown"].as_f64().unwrap();
        let caveat = r["three_state"]["caveat"].as_str();
        let mostly = unknown >= tre::pipeline::MOSTLY_UNKNOWN_SHARE;
        assert_eq!(caveat.is_some(), mostly, "{mode}: {unknown}");
        assert_eq!(
            err.contains("warning: the three-state map is"),
            mostly,
            "{mode}: {err}"
        );
        let warned = r["warnings"].as_array().unwrap();
        assert_eq!(
            warned
                .iter()
                .any(|w| w.as_str().unwrap().contains("unknown")),
            mostly
        );
        for f in r["files"].as_array().unwrap() {
            if let Some(title) = f["title"].as_str() {
                assert_eq!(title.contains("% UNKNOWN"), mostly, "{mode}: {title}");
                assert!(title.contains(&format!("mode {mode}")), "{title}");
            }
        }
        caveats.push((mode, unknown, mostly));
    }
    println!("unknown shares: {caveats:?}");
    // The sensor's own depth answers; the rgb mode's calibrated intervals on this frame do not.
    assert!(!caveats[0].2 && caveats[1].2, "{caveats:?}");
}
