//! Where `tre infer` looks for its models, from outside the checkout too.

use super::*;

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
    crate::common::skip_unless_shared!("data/real-rgbd");
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
