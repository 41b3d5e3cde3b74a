//! `tre eval`: the tables and their JSON, and every mode on a real frame.

use super::*;

/// A tiny synthetic dataset: one 64×64 frame, all of it the test split.
fn tiny_dataset() -> tempfile::TempDir {
    let data = tempfile::tempdir().unwrap();
    let cfg = tre::synth::dataset::SynthConfig {
        test_fraction: 1.0,
        ply: false,
        ..crate::common::synth_config(data.path(), 1, 7, (64, 64), 1)
    };
    tre::synth::dataset::generate(&cfg).unwrap();
    data
}

/// `tre eval --tables --json` prints every table and writes every row.
fn assert_tables_and_json(data: &Path) {
    let json = data.join("tables.json");
    let out = tre(&["eval", "--data", s(data), "--tables", "--json", s(&json)]);
    assert!(out.status.success(), "{}", stderr(&out));
    let text = String::from_utf8_lossy(&out.stdout);
    for needle in [
        "Table II",
        "Table IV",
        "Table V",
        "end-to-end baseline",
        "| rgbd | DSAC+NR+ESR |",
        "AbsRel",
    ] {
        assert!(text.contains(needle), "{needle:?} missing from {text}");
    }
    let report: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(json).unwrap()).unwrap();
    assert_eq!(report["frames"], 1);
    let rows = report["rows"].as_array().unwrap();
    assert_eq!(rows.len(), 13);
    assert!(rows
        .iter()
        .all(|r| r["roughness"]["rmse_cm"].as_f64().is_some()));
}

/// Fewer hypotheses: every row that runs DSAC says so, and every table still finds it; 0 is
/// refused naming the option.
fn assert_fewer_hypotheses_are_named(data: &Path) {
    let four = tre(&[
        "eval",
        "--data",
        s(data),
        "--tables",
        "--dsac-hypotheses",
        "4",
    ]);
    assert!(four.status.success(), "{}", stderr(&four));
    let text = String::from_utf8_lossy(&four.stdout);
    for needle in [
        "| TRENet, RGB (DE+DSAC(K=4)+NR+ESR) |",
        "| rgbd | DSAC(K=4)+NR+ESR |",
        "| rgb | DSAC(K=4)+NR |",
        "| rgbd | DSAC(K=4) |",
        "Depth (rgb mode, rgb:DE+DSAC(K=4)+NR+ESR)",
    ] {
        assert!(text.contains(needle), "{needle:?} missing from {text}");
    }
    assert!(!text.contains("DSAC+"), "a row without K in {text}");
    let bad = tre(&["eval", "--data", s(data), "--dsac-hypotheses", "0"]);
    assert!(!bad.status.success());
    assert!(
        stderr(&bad).contains("--dsac-hypotheses"),
        "{}",
        stderr(&bad)
    );
}

#[test]
fn eval_tables_print_every_table_and_write_json() {
    let data = tiny_dataset();
    assert_tables_and_json(data.path());
    assert_fewer_hypotheses_are_named(data.path());
    let one = tre(&[
        "eval",
        "--data",
        s(data.path()),
        "--mode",
        "rgbd",
        "--normals",
        "ls",
        "--refine",
        "off",
        "--centroid",
        "window",
    ]);
    assert!(one.status.success(), "{}", stderr(&one));
    assert!(String::from_utf8_lossy(&one.stdout).contains("rgbd:LS+window"));
}

#[test]
fn eval_real_scores_every_mode_on_one_frame_and_writes_json_and_a_sheet() {
    crate::common::skip_unless_shared!("data/real-rgbd");
    let dir = tempfile::tempdir().unwrap();
    let (json, sheets) = (dir.path().join("real.json"), dir.path().join("sheets"));
    let o = tre(&[
        "eval",
        "--real",
        real("slambook2_ch7").to_str().unwrap(),
        "--limit",
        "1",
        "--floors",
        "tests/fixtures/real_floor.json",
        "--json",
        json.to_str().unwrap(),
        "--sheets",
        sheets.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let stdout = String::from_utf8_lossy(&o.stdout);
    assert!(stdout.contains("| geometric:LS+window+edge |"), "{stdout}");
    let report: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap();
    assert_eq!(report["frames"], 1);
    let frame = &report["per_frame"][0];
    assert_eq!(frame["name"], "slambook2_ch7/1_depth.png");
    assert_eq!(frame["size"], serde_json::json!([640, 480]));
    assert_eq!(frame["floor_box"], serde_json::json!([240, 455, 500, 478]));
    let spec_floor = frame["spec"]["floor"]["median_cm"].as_f64().unwrap();
    assert!((0.05..1.0).contains(&spec_floor), "spec floor {spec_floor}");
    let rows = report["pooled"].as_array().unwrap();
    let keys: Vec<&str> = rows.iter().map(|r| r["key"].as_str().unwrap()).collect();
    assert_eq!(
        keys,
        [
            "rgb:DE+DSAC+NR+ESR",
            "rgbd:DSAC+NR+ESR",
            "geometric:terrain",
            "geometric:LS+window+edge",
            "geometric:LS+window",
            "geometric:cleaned+LS+window+edge"
        ]
    );
    for r in rows {
        assert_pooled_row(r);
    }
    assert_modes_compare(rows);
    let sheet = image::open(sheets.join("slambook2_ch7_1_depth.png")).unwrap();
    assert!(sheet.width() >= 3 * 320 && sheet.height() >= 2 * 240);
}

/// A number within 0..=1.
fn unit(v: &serde_json::Value) -> Option<f64> {
    v.as_f64().filter(|x| (0.0..=1.0).contains(x))
}

/// One pooled row of `eval --real`: its scores in range, its range bins adding up to the whole.
fn assert_pooled_row(r: &serde_json::Value) {
    let key = r["key"].as_str().unwrap();
    assert!(unit(&r["all"]["edge_recall"]).is_some(), "{key}");
    assert!(unit(&r["all"]["false_hazards"]).is_some(), "{key}");
    assert!(r["all"]["edges"].as_u64().unwrap() > 1000, "{key}");
    assert!(r["all"]["roughness"]["rmse_cm"].as_f64().unwrap() >= 0.0);
    assert!(r["floor"]["p90_cm"].as_f64().unwrap() >= r["floor"]["median_cm"].as_f64().unwrap());
    assert!(r["ms"]["total"].as_f64().unwrap() > 0.0, "{key}");
    let ranges: Vec<&String> = r["by_range"].as_object().unwrap().keys().collect();
    assert_eq!(ranges, ["0_2m", "2_4m", "4m_up"], "{key}");
    let pixels: u64 = r["by_range"]
        .as_object()
        .unwrap()
        .values()
        .map(|b| b["roughness"]["pixels"].as_u64().unwrap())
        .sum();
    assert_eq!(
        pixels,
        r["all"]["roughness"]["pixels"].as_u64().unwrap(),
        "{key}"
    );
}

/// The pooled rows against each other: rows 0-1 the learned modes, 2 the terrain estimate, 3
/// the spec, 4 the surface-only baseline. The spec row is the spec; the surface-only baseline
/// misses the drops; the three-state map and the depth errors where they apply.
fn assert_modes_compare(rows: &[serde_json::Value]) {
    // The spec row is the spec: nothing missed, nothing invented.
    assert_eq!(rows[3]["all"]["edge_recall"], 1.0);
    assert_eq!(rows[3]["all"]["false_hazards"], 0.0);
    assert_eq!(rows[3]["all"]["roughness"]["rmse_cm"], 0.0);
    // The surface-only baseline misses the drops.
    assert!(rows[4]["all"]["edge_recall"].as_f64().unwrap() < 0.2);
    // The terrain estimate is scored against truths of its own (tests/it/regions.rs): against
    // the spec, whose hazards include its noise at range and a wider edge band, it reads a
    // fifth of them on this frame (docs/terrain.md).
    let recall = rows[2]["all"]["edge_recall"].as_f64().unwrap();
    assert!(recall > 0.1 && recall < 1.0, "{recall}");
    // The three-state map of every row: the learned modes and the spec through the committed
    // calibrated intervals, the terrain estimate and the surface-only baseline under the
    // Kinect model alone; the spec's near floor traversable, its drops hazards.
    for r in rows {
        let safety = &r["safety"];
        assert!(unit(&safety["all"]["missed_hazards"]).is_some(), "{safety}");
        assert!(unit(&safety["all"]["floor_coverage"]).is_some(), "{safety}");
    }
    let target = |i: usize| rows[i]["safety"]["coverage_target"].as_str().unwrap();
    assert_eq!(
        [target(0), target(1), target(2), target(4)],
        ["same depth", "same depth", "none", "none"]
    );
    assert!(unit(&rows[0]["safety"]["all"]["interval_coverage"]).is_some());
    // The spec never reads one of its own hazards traversable.
    assert_eq!(rows[3]["safety"]["all"]["missed_hazards"], 0.0);
    let states = &rows[3]["traversal"];
    assert!(
        states["near_floor"]["traversable"].as_f64().unwrap() > 0.9,
        "{states}"
    );
    // A drop is never traversable; through the intervals it is a hazard where even the
    // lower end of its interval is above 5 cm, and unknown where another view of it could
    // read less (docs/uncertainty.md).
    assert_eq!(states["near_drops"]["traversable"], 0.0, "{states}");
    assert!(
        states["near_drops"]["hazard"].as_f64().unwrap() > 0.3,
        "{states}"
    );
    let shares = ["traversable", "hazard", "unknown"]
        .map(|k| states["all"][k].as_f64().unwrap())
        .iter()
        .sum::<f64>();
    assert!((shares - 1.0).abs() < 1e-9, "{states}");
    // Depth errors only for rgb, against the sensor.
    let depth = &rows[0]["depth"];
    assert!(depth["abs_rel"].as_f64().unwrap() > 0.0);
    assert!(unit(&depth["delta_1_25"]).is_some());
    assert!(rows[1]["depth"].is_null());
}

#[test]
fn eval_real_pools_folders_and_scores_only_the_split_asked_for() {
    let Some(kitchen) = shared_data("data/real-rgbd")
        .and_then(|_| shared_data("data/real-rgbd-2/sevenscenes_redkitchen"))
    else {
        return;
    };
    let dir = tempfile::tempdir().unwrap();
    let json = dir.path().join("split.json");
    let o = tre(&[
        "eval",
        "--real",
        s(&real("slambook2_ch7")),
        "--real",
        s(&kitchen),
        "--real-splits",
        "models/real_splits.json",
        "--split",
        "test",
        "--modes",
        "geometric",
        "--limit",
        "4",
        "--json",
        s(&json),
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let report: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap();
    let names: Vec<&str> = report["per_frame"]
        .as_array()
        .unwrap()
        .iter()
        .map(|f| f["name"].as_str().unwrap())
        .collect();
    // The two TUM frames, then the kitchen's first test frames (list 160 on: frame-000800).
    assert_eq!(
        names,
        [
            "slambook2_ch7/1_depth.png",
            "slambook2_ch7/2_depth.png",
            "sevenscenes_redkitchen/depth/frame-000800.png",
            "sevenscenes_redkitchen/depth/frame-000805.png"
        ]
    );
    assert_eq!(report["split"], "test");
    // Its log went to a pipe: no colour escape codes in it.
    assert!(stderr(&o).contains("INFO") && !stderr(&o).contains('\u{1b}'));
    // The kitchen has poses: its second test frame checks the spec's interval against the
    // first one's view of the same surfaces.
    // Rows: the terrain estimate, the spec, the surface-only baseline.
    let spec = &report["per_sequence"]["sevenscenes_redkitchen"][1]["safety"];
    assert_eq!(spec["coverage_target"], "another view", "{spec}");
    let cov = unit(&spec["all"]["interval_coverage"]).unwrap();
    assert!(cov > 0.7, "{spec}");
    assert!(
        spec["all"]["interval_px"].as_u64().unwrap() > 50_000,
        "{spec}"
    );
    let stdout = String::from_utf8_lossy(&o.stdout);
    assert!(stdout.contains("By sequence folder"), "{stdout}");
}

/// `tre eval --real` on the TUM pair and the kitchen's first test frames against
/// `reference`: its JSON report.
fn eval_against(kitchen: &Path, dir: &Path, reference: &str) -> serde_json::Value {
    let json = dir.join(format!("{reference}.json"));
    let o = tre(&[
        "eval",
        "--real",
        s(&real("slambook2_ch7")),
        "--real",
        s(kitchen),
        "--real-splits",
        "models/real_splits.json",
        "--modes",
        "geometric",
        "--limit",
        "6",
        "--reference",
        reference,
        "--json",
        s(&json),
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap()
}

/// The pooled RMSE (cm) of the spec on raw depth in a report.
fn spec_rmse(report: &serde_json::Value) -> f64 {
    let row = report["pooled"]
        .as_array()
        .unwrap()
        .iter()
        .find(|r| r["key"] == "geometric:LS+window+edge")
        .unwrap();
    row["all"]["roughness"]["rmse_cm"].as_f64().unwrap()
}

/// `--reference fused`: the kitchen's test frames scored against the spec on depth fused from
/// their neighbours; a frame without a pose (TUM) is left out, and the spec on the raw depth is
/// no longer its own reference (it was, with RMSE 0, under `--reference raw`).
#[test]
fn eval_real_against_the_fused_reference_leaves_out_unposed_frames() {
    let Some(kitchen) = shared_data("data/real-rgbd")
        .and_then(|_| shared_data("data/real-rgbd-2/sevenscenes_redkitchen"))
    else {
        return;
    };
    let dir = tempfile::tempdir().unwrap();
    let raw = eval_against(&kitchen, dir.path(), "raw");
    assert_eq!(
        (raw["reference"].as_str(), raw["frames"].as_u64()),
        (Some("raw"), Some(6))
    );
    assert!(spec_rmse(&raw).abs() < 1e-9);
    let fused = eval_against(&kitchen, dir.path(), "fused");
    assert_eq!(fused["reference"], "fused");
    // The two TUM frames have no pose: only the kitchen's four are scored.
    assert_eq!(fused["frames"], 4);
    let names: Vec<&str> = fused["per_frame"]
        .as_array()
        .unwrap()
        .iter()
        .map(|f| f["name"].as_str().unwrap())
        .collect();
    assert!(
        names
            .iter()
            .all(|n| n.starts_with("sevenscenes_redkitchen/")),
        "{names:?}"
    );
    let rmse = spec_rmse(&fused);
    assert!(
        rmse > 0.1,
        "the spec on raw depth against the fused one: RMSE {rmse} cm"
    );
}

#[test]
fn unsplit_sequences_and_calibrating_on_the_test_split_are_refused() {
    let Some(kitchen) = shared_data("data/real-rgbd")
        .and_then(|_| shared_data("data/real-rgbd-2/sevenscenes_redkitchen"))
    else {
        return;
    };
    let dir = tempfile::tempdir().unwrap();
    // A sequence the splits file does not name is refused, not scored silently.
    let other = dir.path().join("elsewhere");
    std::fs::create_dir(&other).unwrap();
    for f in std::fs::read_dir(real("slambook2_ch7")).unwrap() {
        let f = f.unwrap();
        std::fs::copy(f.path(), other.join(f.file_name())).unwrap();
    }
    fails_saying(
        &[
            "eval",
            "--real",
            s(&other),
            "--real-splits",
            "models/real_splits.json",
            "--modes",
            "geometric",
        ],
        "\"elsewhere\" has no split",
    );
    fails_saying(
        &[
            "calibrate",
            "--real",
            s(&kitchen),
            "--split",
            "test",
            "--out",
            s(&dir.path().join("u.json")),
        ],
        "fit them on val",
    );
}
