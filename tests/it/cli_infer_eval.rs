//! `tre infer` and `tre eval` end to end through the binary: outputs on a real frame in every
//! mode, clear errors for bad input, the models found from outside the checkout,
//! `eval --tables --json` on a tiny synthetic dataset and `eval --real` on a real frame.
#![allow(clippy::unwrap_used)] // Test helpers fail loudly by design.

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

fn tre(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_tre"))
        .current_dir(env!("CARGO_MANIFEST_DIR"))
        .env("TRE_ORT_THREADS", "1")
        .args(args)
        .output()
        .expect("runs tre")
}

fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

/// Runs `tre args`, which must fail with a message holding `needle` (and no panic).
fn fails_saying(args: &[&str], needle: &str) {
    let o = tre(args);
    let err = stderr(&o);
    assert!(!o.status.success(), "{args:?} should fail");
    assert!(!err.contains("panicked"), "{args:?}: {err}");
    assert!(
        err.contains(needle),
        "{args:?}: expected {needle:?} in {err}"
    );
}

fn real(rel: &str) -> PathBuf {
    Path::new(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../shared/data/real-rgbd"
    ))
    .join(rel)
}

fn s(p: &Path) -> &str {
    p.to_str().unwrap()
}

#[test]
fn infer_writes_roughness_and_a_preview_in_every_mode() {
    let dir = tempfile::tempdir().unwrap();
    let rgb = real("slambook2_ch5/color/1.png");
    let depth = real("slambook2_ch5/depth/1.png");
    let camera = real("slambook2_ch5/intrinsics.json");
    let runs: [(&str, Vec<&str>); 4] = [
        ("rgb.png", vec![s(&rgb), "--camera", s(&camera)]),
        (
            "rgbd.png",
            vec![s(&rgb), "--depth", s(&depth), "--camera", s(&camera)],
        ),
        (
            "geo.npy",
            vec![
                "--depth",
                s(&depth),
                "--camera",
                s(&camera),
                "--format",
                "npy",
            ],
        ),
        ("e2e.png", vec![s(&rgb), "--method", "end-to-end"]),
    ];
    for (name, args) in runs {
        let out_path = dir.path().join(name);
        let mut all = vec!["infer", "-o", s(&out_path)];
        all.extend(args);
        let out = tre(&all);
        assert!(out.status.success(), "{name}: {}", stderr(&out));
        let stem = name.split('.').next().unwrap();
        assert!(
            dir.path().join(format!("{stem}_preview.png")).is_file(),
            "{name}"
        );
        if name.ends_with(".png") {
            let img = tre::io::read_image(&out_path).unwrap();
            assert_eq!((img.width(), img.height()), (640, 480), "{name}");
            let r = tre::io::decode_roughness_png16(&img);
            assert!(r.as_slice().iter().filter(|v| v.is_finite()).count() > 100_000);
        } else {
            let a = tre::io::npy::read_npy(std::fs::File::open(&out_path).unwrap()).unwrap();
            assert_eq!(a.shape, vec![480, 640]);
        }
    }
}

#[test]
fn infer_takes_the_traversability_thresholds() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("geo.npy");
    let depth = real("slambook2_ch5/depth/1.png");
    let camera = real("slambook2_ch5/intrinsics.json");
    let base = [
        "infer",
        "--format",
        "npy",
        "-o",
        s(&out),
        "--depth",
        s(&depth),
    ];
    let counts = |extra: &[&str]| -> (usize, usize) {
        let mut args = base.to_vec();
        args.extend(["--camera", s(&camera)]);
        args.extend(extra);
        let o = tre(&args);
        assert!(o.status.success(), "{extra:?}: {}", stderr(&o));
        let text = String::from_utf8_lossy(&o.stdout).into_owned();
        // "LS+window at 640×480: N px with roughness, median … cm, M px traversable"
        let number_before = |what: &str| -> usize {
            let head = &text[..text
                .find(what)
                .unwrap_or_else(|| panic!("{what} in {text}"))];
            head.split_whitespace().last().unwrap().parse().unwrap()
        };
        (
            number_before(" px traversable"),
            number_before(" px with roughness"),
        )
    };
    let (default, valid) = counts(&[]);
    assert!(0 < default && default < valid, "{default} of {valid}");
    let loose = counts(&["--max-roughness-cm", "10000", "--max-slope-deg", "90"]);
    assert_eq!(loose, (valid, valid));
    let strict = counts(&["--max-roughness-cm", "1", "--max-slope-deg", "5"]);
    assert!(strict.0 < default, "{strict:?} against {default}");
    let mut args = base.to_vec();
    args.extend(["--max-slope-deg", "95"]);
    fails_saying(&args, "--max-slope-deg: must be 0 to 90");
}

#[test]
fn infer_refuses_bad_input_clearly() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("r.png");
    let rgb = real("slambook2_ch5/color/1.png");
    let small_depth = real("slambook2_ch7/1_depth.png");
    let depth_of_other_size = tre::io::read_depth(&small_depth, 5000.0).unwrap();
    let cut = tre::geometry::Grid::from_fn(320, 240, |x, y| depth_of_other_size[(x, y)]);
    let cut_path = dir.path().join("cut.png");
    tre::io::save(
        &cut_path,
        &image::DynamicImage::ImageLuma16(tre::io::depth_png16(&cut)),
    )
    .unwrap();
    let garbage = dir.path().join("garbage.png");
    std::fs::write(&garbage, b"not a png at all").unwrap();
    let cases: [(Vec<&str>, &str); 4] = [
        (vec![s(&rgb), "--depth", s(&cut_path)], "320×240"),
        (
            vec![s(&rgb), "--depth", s(&cut_path), "--method", "end-to-end"],
            "RGB alone",
        ),
        (vec![s(&garbage), "--mode", "rgb"], "not a readable image"),
        (
            vec![
                "--depth",
                s(&cut_path),
                "--models",
                "/nonexistent",
                "--mode",
                "rgbd",
            ],
            "rgb",
        ),
    ];
    for (args, needle) in cases {
        let mut all = vec!["infer", "-o", s(&out)];
        all.extend(args.iter().copied());
        fails_saying(&all, needle);
    }
    // Each cause is said once (the errors' chain once repeated it).
    let missing = dir.path().join("missing.png");
    let o = tre(&["infer", s(&missing), "-o", s(&out)]);
    assert_eq!(
        stderr(&o).matches("No such file").count(),
        1,
        "{}",
        stderr(&o)
    );
}

/// No command writes over its inputs, and inputs that cannot be right (depth with no valid
/// pixel or in millimetres, a focal length in millimetres, a map in a format that cannot hold
/// it) are refused before any work, each with a message that names the problem.
#[test]
fn outputs_never_replace_inputs_and_implausible_inputs_are_refused() {
    let dir = tempfile::tempdir().unwrap();
    let p = |name: &str| dir.path().join(name);
    let frame = p("frame.png");
    std::fs::copy(real("slambook2_ch5/color/1.png"), &frame).unwrap();
    let original = std::fs::read(&frame).unwrap();
    let npy = |name: &str, value: f32| {
        let path = p(name);
        let f = std::fs::File::create(&path).unwrap();
        tre::io::npy::write_npy(f, &[48, 64], &vec![value; 48 * 64]).unwrap();
        path
    };
    let zero = npy("zero.npy", 0.0);
    let millimetres = npy("mm.npy", 1500.0);
    let depth = p("depth.png");
    std::fs::copy(real("slambook2_ch5/depth/1.png"), &depth).unwrap();
    let mm_focal = p("mm_focal.json");
    std::fs::write(
        &mm_focal,
        r#"{"fx": 3.6, "fy": 3.6, "cx": 319.5, "cy": 239.5}"#,
    )
    .unwrap();
    let flat_fy = p("flat_fy.json");
    std::fs::write(
        &flat_fy,
        r#"{"fx": 518, "fy": 0.001, "cx": 325.5, "cy": 253.5}"#,
    )
    .unwrap();
    let elsewhere = p("out/r.png");
    let (jpg, annotated, manifest) = (p("r.jpg"), p("a"), p("dataset.json"));
    std::fs::write(&manifest, b"{}").unwrap();
    let cases: Vec<(Vec<&str>, &str)> = vec![
        (vec!["infer", s(&frame), "-o", s(&frame)], "input"),
        (vec!["infer", s(&frame), "-o", s(&jpg)], ".png"),
        (
            vec![
                "infer",
                s(&frame),
                "-o",
                s(&elsewhere),
                "--preview-max-cm",
                "0",
            ],
            "--preview-max-cm",
        ),
        (
            vec!["infer", "--depth", s(&zero), "-o", s(&elsewhere)],
            "no valid pixel",
        ),
        (
            vec!["infer", "--depth", s(&millimetres), "-o", s(&elsewhere)],
            "millimetres",
        ),
        (
            vec![
                "infer",
                "--depth",
                s(&depth),
                "--camera",
                s(&mm_focal),
                "-o",
                s(&elsewhere),
            ],
            "focal length in pixels",
        ),
        (
            vec![
                "annotate",
                "--depth",
                s(&depth),
                "--camera",
                s(&flat_fy),
                "--out",
                s(&annotated),
            ],
            "field of view",
        ),
        (
            vec![
                "annotate",
                "--depth",
                s(&depth),
                "--camera",
                s(&mm_focal),
                "--out",
                s(dir.path()),
            ],
            "holds the input",
        ),
        (
            vec!["eval", "--data", s(dir.path()), "--json", s(&manifest)],
            "over or inside the input",
        ),
        (
            vec![
                "loadtest",
                "--frame",
                s(&frame),
                "--json",
                s(&frame),
                "--requests",
                "1",
            ],
            "input",
        ),
    ];
    for (args, needle) in cases {
        fails_saying(&args, needle);
    }
    assert_eq!(
        std::fs::read(&frame).unwrap(),
        original,
        "the frame was written over"
    );
    assert!(!elsewhere.exists() && !jpg.exists());
    assert_eq!(
        std::fs::read(&manifest).unwrap(),
        b"{}",
        "the manifest was written over"
    );
}

#[test]
fn eval_tables_print_every_table_and_write_json() {
    let data = tempfile::tempdir().unwrap();
    let cfg = tre::synth::SynthConfig {
        out: data.path().to_owned(),
        scenes: 1,
        seed: 7,
        size: (64, 64),
        views: 1,
        test_fraction: 1.0,
        ply: false,
        ..tre::synth::SynthConfig::default()
    };
    tre::synth::generate(&cfg).unwrap();
    let json = data.path().join("tables.json");
    let out = tre(&[
        "eval",
        "--data",
        s(data.path()),
        "--tables",
        "--json",
        s(&json),
    ]);
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

    // Fewer hypotheses: every row that runs DSAC says so, and every table still finds it.
    let four = tre(&[
        "eval",
        "--data",
        s(data.path()),
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
    let bad = tre(&["eval", "--data", s(data.path()), "--dsac-hypotheses", "0"]);
    assert!(!bad.status.success());
    assert!(
        stderr(&bad).contains("--dsac-hypotheses"),
        "{}",
        stderr(&bad)
    );

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
            "geometric:LS+window+edge",
            "geometric:LS+window"
        ]
    );
    let unit = |v: &serde_json::Value| v.as_f64().filter(|x| (0.0..=1.0).contains(x));
    for r in rows {
        let key = r["key"].as_str().unwrap();
        assert!(unit(&r["all"]["edge_recall"]).is_some(), "{key}");
        assert!(unit(&r["all"]["false_hazards"]).is_some(), "{key}");
        assert!(r["all"]["edges"].as_u64().unwrap() > 1000, "{key}");
        assert!(r["all"]["roughness"]["rmse_cm"].as_f64().unwrap() >= 0.0);
        assert!(
            r["floor"]["p90_cm"].as_f64().unwrap() >= r["floor"]["median_cm"].as_f64().unwrap()
        );
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
    // The geometric mode is the spec: nothing missed, nothing invented.
    assert_eq!(rows[2]["all"]["edge_recall"], 1.0);
    assert_eq!(rows[2]["all"]["false_hazards"], 0.0);
    assert_eq!(rows[2]["all"]["roughness"]["rmse_cm"], 0.0);
    // The surface-only baseline misses the drops.
    assert!(rows[3]["all"]["edge_recall"].as_f64().unwrap() < 0.2);
    // The three-state map under the Kinect model: for the modes that read sensor depth only;
    // the spec's near floor traversable, its drops hazards.
    assert!(rows[0]["traversal"].is_null());
    let states = &rows[2]["traversal"];
    assert!(
        states["near_floor"]["traversable"].as_f64().unwrap() > 0.9,
        "{states}"
    );
    assert!(
        states["near_drops"]["hazard"].as_f64().unwrap() > 0.9,
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
    let sheet = image::open(sheets.join("slambook2_ch7_1_depth.png")).unwrap();
    assert!(sheet.width() >= 3 * 320 && sheet.height() >= 2 * 240);
}

/// `tre ARGS` run from `cwd` (outside the checkout) with `TRE_MODELS` set to `models` or unset.
fn tre_in(cwd: &Path, models: Option<&Path>, args: &[&str]) -> Output {
    let mut cmd = Command::new(env!("CARGO_BIN_EXE_tre"));
    cmd.current_dir(cwd)
        .env("TRE_ORT_THREADS", "1")
        .env("TRE_LOG", "info,ort=warn")
        .env_remove("TRE_MODELS");
    if let Some(dir) = models {
        cmd.env("TRE_MODELS", dir);
    }
    cmd.args(args).output().expect("runs tre")
}

#[test]
fn infer_finds_the_models_from_outside_the_checkout_and_says_where() {
    let cwd = tempfile::tempdir().unwrap();
    let frame = cwd.path().join("frame.png");
    image::RgbImage::from_fn(64, 48, |x, y| {
        image::Rgb([(x * 4) as u8, (y * 5) as u8, 90])
    })
    .save(&frame)
    .unwrap();
    let out = cwd.path().join("r.png");
    let args = ["infer", s(&frame), "-o", s(&out), "--normals", "ls"];
    let checkout_models = Path::new(env!("CARGO_MANIFEST_DIR")).join("models");
    let shown = checkout_models
        .canonicalize()
        .unwrap()
        .display()
        .to_string();

    // TRE_MODELS names the checkout's models: found, and the log says where and why.
    let o = tre_in(cwd.path(), Some(&checkout_models), &args);
    let err = stderr(&o);
    assert!(o.status.success(), "{err}");
    assert!(out.is_file());
    assert!(
        err.contains(&shown) && err.contains("found by TRE_MODELS"),
        "{err}"
    );

    // --models wins over TRE_MODELS, even one that names an empty folder.
    let empty = tempfile::tempdir().unwrap();
    let mut with_flag = args.to_vec();
    with_flag.extend(["--models", s(&checkout_models)]);
    let o = tre_in(cwd.path(), Some(empty.path()), &with_flag);
    let err = stderr(&o);
    assert!(o.status.success(), "{err}");
    assert!(
        err.contains(&shown) && err.contains("found by --models"),
        "{err}"
    );

    // TRE_MODELS naming a folder without a manifest is refused, not skipped.
    let o = tre_in(cwd.path(), Some(empty.path()), &args);
    let err = stderr(&o);
    assert!(!o.status.success() && !err.contains("panicked"), "{err}");
    let empty_shown = empty.path().display().to_string();
    assert!(
        err.contains(&format!("TRE_MODELS names {empty_shown}")),
        "{err}"
    );
    assert!(err.contains("manifest.json"), "{err}");
}

#[test]
fn infer_without_models_lists_every_place_looked_at_in_order() {
    let exe_dir = Path::new(env!("CARGO_BIN_EXE_tre")).parent().unwrap();
    let beside = exe_dir.join("models");
    let share = exe_dir.join("../share/tre/models");
    for dir in [&beside, &share] {
        assert!(
            !dir.join("manifest.json").exists(),
            "this test needs no models at {}; remove them",
            dir.display()
        );
    }
    let cwd = tempfile::tempdir().unwrap();
    let cwd_models = cwd.path().join("models").display().to_string();
    let frame = real("slambook2_ch5/color/1.png");
    let out = cwd.path().join("r.png");
    let o = tre_in(cwd.path(), None, &["infer", s(&frame), "-o", s(&out)]);
    let err = stderr(&o);
    assert!(!o.status.success() && !err.contains("panicked"), "{err}");
    let at = |path: &str| {
        err.find(path)
            .unwrap_or_else(|| panic!("{path} missing from: {err}"))
    };
    let (b, sh, w) = (
        at(&beside.display().to_string()),
        at(&share.display().to_string()),
        at(&cwd_models),
    );
    assert!(b < sh && sh < w, "not in search order: {err}");
    assert!(
        err.contains("--models DIR") && err.contains("TRE_MODELS=DIR"),
        "{err}"
    );
    assert!(!out.exists());
}
