//! `tre annotate` end to end: outputs on a real frame, and a clear error (never a panic) for
//! each kind of bad input.
#![allow(clippy::unwrap_used)] // Test helpers fail loudly by design.

use std::path::Path;

use crate::common::{real, s, stderr, tre};

/// Runs annotate and expects failure with `needle` in the message and no panic.
fn expect_error(args: &[&str], needle: &str) {
    let out = tre(args);
    let err = stderr(&out);
    assert!(!out.status.success(), "expected failure for {args:?}");
    assert!(!err.contains("panicked"), "panic for {args:?}: {err}");
    assert!(
        err.contains(needle),
        "{args:?}: expected {needle:?} in {err:?}"
    );
}

/// `tre annotate --depth DEPTH --camera CAMERA -o OUT` fails with `needle` and no panic.
fn expect_annotate_error(depth: &Path, camera: &Path, out: &Path, needle: &str) {
    expect_error(
        &[
            "annotate",
            "--depth",
            s(depth),
            "--camera",
            s(camera),
            "-o",
            s(out),
        ],
        needle,
    );
}

#[test]
fn annotates_a_real_frame_with_every_output() {
    crate::common::skip_unless_shared!("data/real-rgbd");
    let dir = tempfile::tempdir().unwrap();
    let out = tre(&[
        "annotate",
        "--depth",
        s(&real("slambook2_ch7/1_depth.png")),
        "--camera",
        s(&real("slambook2_ch7/intrinsics.json")),
        "--out",
        s(dir.path()),
    ]);
    assert!(out.status.success(), "{}", stderr(&out));
    for f in [
        "roughness.png",
        "roughness.npy",
        "boundary.png",
        "edge_weight.npy",
        "segments.npy",
        "preview.png",
    ] {
        assert!(dir.path().join(f).is_file(), "{f} missing");
    }
    // The 16-bit PNG decodes back to the float map within half a unit (0.05 mm).
    let png = image::open(dir.path().join("roughness.png")).unwrap();
    let from_png = tre::io::decode_roughness_png16(&png);
    let npy =
        tre::io::npy::read_npy(std::fs::File::open(dir.path().join("roughness.npy")).unwrap())
            .unwrap();
    assert_eq!(npy.shape, vec![480, 640]);
    for (a, b) in from_png.as_slice().iter().zip(&npy.data) {
        assert_eq!(a.is_nan(), b.is_nan());
        if b.is_finite() && *b < 6.5 {
            assert!((a - b).abs() <= 0.5e-4 + 1e-7, "{a} vs {b}");
        }
    }
    assert!(String::from_utf8_lossy(&out.stdout).contains("roughness cm: median"));
}

#[test]
fn bad_inputs_give_clear_errors() {
    crate::common::skip_unless_shared!("data/real-rgbd");
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let cam = real("slambook2_ch7/intrinsics.json");
    let depth = real("slambook2_ch7/1_depth.png");
    let out = d.join("out");

    // Not an image at all.
    std::fs::write(d.join("junk.png"), b"this is not a png").unwrap();
    expect_annotate_error(&d.join("junk.png"), &cam, &out, "not a readable image");

    // A truncated PNG.
    let bytes = std::fs::read(&depth).unwrap();
    std::fs::write(d.join("cut.png"), &bytes[..bytes.len() / 3]).unwrap();
    expect_annotate_error(&d.join("cut.png"), &cam, &out, "cut.png");

    // A colour image given as depth.
    expect_annotate_error(
        &real("slambook2_ch7/1.png"),
        &cam,
        &out,
        "depth must be a 16-bit grey PNG",
    );

    // Intrinsics for another image size.
    let mut json: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&cam).unwrap()).unwrap();
    json["width"] = 320.into();
    std::fs::write(d.join("small.json"), json.to_string()).unwrap();
    expect_annotate_error(
        &depth,
        &d.join("small.json"),
        &out,
        "describes a 320×480 image",
    );

    // A non-positive focal length.
    json["width"] = 640.into();
    json["fx"] = (-5.0).into();
    std::fs::write(d.join("neg.json"), json.to_string()).unwrap();
    expect_annotate_error(
        &depth,
        &d.join("neg.json"),
        &out,
        "focal length fx must be positive",
    );

    // Camera JSON that is not JSON.
    std::fs::write(d.join("bad.json"), "{fx: ").unwrap();
    expect_annotate_error(&depth, &d.join("bad.json"), &out, "bad camera JSON");

    // All-invalid depth.
    let zeros = image::ImageBuffer::<image::Luma<u16>, Vec<u16>>::new(640, 480);
    zeros.save(d.join("zeros.png")).unwrap();
    expect_annotate_error(&d.join("zeros.png"), &cam, &out, "has no valid pixel");

    // A missing file.
    expect_annotate_error(&d.join("nope.png"), &cam, &out, "nope.png: No such file");
}
