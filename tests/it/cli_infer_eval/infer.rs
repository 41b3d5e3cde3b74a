//! `tre infer`: every mode, the traversability thresholds, bad input refused clearly, outputs
//! that never replace inputs.

use super::*;

#[test]
fn infer_writes_roughness_and_a_preview_in_every_mode() {
    crate::common::skip_unless_shared!("data/real-rgbd");
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
    crate::common::skip_unless_shared!("data/real-rgbd");
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("geo.npy");
    let depth = real("slambook2_ch5/depth/1.png");
    // The shared camera with a stated pitch, so that slope is judged against stated gravity.
    let mut cam: serde_json::Value =
        serde_json::from_slice(&std::fs::read(real("slambook2_ch5/intrinsics.json")).unwrap())
            .unwrap();
    cam["pitch_deg"] = serde_json::json!(30.0);
    let camera = dir.path().join("camera.json");
    std::fs::write(&camera, cam.to_string()).unwrap();
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
        // "mode geometric (…) at 640×480: N px with roughness, median … cm" and
        // "binary map: M px with roughness < 5 cm and slope < 20°"
        let number_before = |what: &str| -> usize {
            let head = &text[..text
                .find(what)
                .unwrap_or_else(|| panic!("{what} in {text}"))];
            head.split_whitespace().last().unwrap().parse().unwrap()
        };
        let binary = &text[text.find("binary map: ").unwrap() + "binary map: ".len()..];
        let traversable = binary.split_whitespace().next().unwrap().parse().unwrap();
        (traversable, number_before(" px with roughness,"))
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
    crate::common::skip_unless_shared!("data/real-rgbd");
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

/// The files that the refusals below are tried on, in a temporary folder.
struct Inputs {
    dir: tempfile::TempDir,
    frame: PathBuf,
    zero: PathBuf,
    millimetres: PathBuf,
    depth: PathBuf,
    mm_focal: PathBuf,
    flat_fy: PathBuf,
    elsewhere: PathBuf,
    jpg: PathBuf,
    annotated: PathBuf,
    manifest: PathBuf,
}

impl Inputs {
    fn new() -> Self {
        let dir = tempfile::tempdir().unwrap();
        let p = |name: &str| dir.path().join(name);
        let frame = p("frame.png");
        std::fs::copy(real("slambook2_ch5/color/1.png"), &frame).unwrap();
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
        Self {
            dir,
            frame,
            zero,
            millimetres,
            depth,
            mm_focal,
            flat_fy,
            elsewhere,
            jpg,
            annotated,
            manifest,
        }
    }

    /// `tre infer` runs that must fail, each with what its message names.
    fn infer_cases(&self) -> Vec<(Vec<&str>, &str)> {
        let (frame, elsewhere) = (&self.frame, &self.elsewhere);
        vec![
            (vec!["infer", s(frame), "-o", s(frame)], "input"),
            (vec!["infer", s(frame), "-o", s(&self.jpg)], ".png"),
            (
                vec![
                    "infer",
                    s(frame),
                    "-o",
                    s(elsewhere),
                    "--preview-max-cm",
                    "0",
                ],
                "--preview-max-cm",
            ),
            (
                vec!["infer", "--depth", s(&self.zero), "-o", s(elsewhere)],
                "no valid pixel",
            ),
            (
                vec!["infer", "--depth", s(&self.millimetres), "-o", s(elsewhere)],
                "millimetres",
            ),
            (
                vec![
                    "infer",
                    "--depth",
                    s(&self.depth),
                    "--camera",
                    s(&self.mm_focal),
                    "-o",
                    s(elsewhere),
                ],
                "focal length in pixels",
            ),
        ]
    }

    /// `tre annotate`, `tre eval` and `tre loadtest` runs that must fail, each with what its
    /// message names.
    fn other_cases(&self) -> Vec<(Vec<&str>, &str)> {
        let dir = self.dir.path();
        vec![
            (
                vec![
                    "annotate",
                    "--depth",
                    s(&self.depth),
                    "--camera",
                    s(&self.flat_fy),
                    "--out",
                    s(&self.annotated),
                ],
                "field of view",
            ),
            (
                vec![
                    "annotate",
                    "--depth",
                    s(&self.depth),
                    "--camera",
                    s(&self.mm_focal),
                    "--out",
                    s(dir),
                ],
                "holds the input",
            ),
            (
                vec!["eval", "--data", s(dir), "--json", s(&self.manifest)],
                "over or inside the input",
            ),
            (
                vec![
                    "loadtest",
                    "--frame",
                    s(&self.frame),
                    "--json",
                    s(&self.frame),
                    "--requests",
                    "1",
                ],
                "input",
            ),
        ]
    }
}

/// No command writes over its inputs, and inputs that cannot be right (depth with no valid
/// pixel or in millimetres, a focal length in millimetres, a map in a format that cannot hold
/// it) are refused before any work, each with a message that names the problem.
#[test]
fn outputs_never_replace_inputs_and_implausible_inputs_are_refused() {
    crate::common::skip_unless_shared!("data/real-rgbd");
    let inputs = Inputs::new();
    let original = std::fs::read(&inputs.frame).unwrap();
    for (args, needle) in inputs.infer_cases().into_iter().chain(inputs.other_cases()) {
        fails_saying(&args, needle);
    }
    assert_eq!(
        std::fs::read(&inputs.frame).unwrap(),
        original,
        "the frame was written over"
    );
    assert!(!inputs.elsewhere.exists() && !inputs.jpg.exists());
    assert_eq!(
        std::fs::read(&inputs.manifest).unwrap(),
        b"{}",
        "the manifest was written over"
    );
}
