//! `tre map` on real kitchen frames with their poses: every layer written in both encodings with
//! the geometry stated, the PNG decoding to the `.npy` by `map.json`'s scale, and a pose that is
//! not a rigid transform skipped with a message while the map keeps the other frames; its
//! `--record` file (in a folder it makes) read by an independent MCAP reader, the map in it
//! equal to the layers.
#![allow(clippy::unwrap_used)] // Test helpers fail loudly by design.

use std::path::Path;
use std::process::Command;

use crate::common::{check_mcap, npy_f32, shared_data};

/// Six kitchen frames of `src` (`../shared/data/real-rgbd-2/sevenscenes_redkitchen`) in a
/// sequence folder of the layout `tre map` reads, the fourth pose broken (a scaled rotation).
fn sequence(src: &Path, dir: &Path) {
    for sub in ["depth", "poses"] {
        std::fs::create_dir_all(dir.join(sub)).unwrap();
    }
    for (n, i) in (0..30).step_by(5).enumerate() {
        let stem = format!("frame-{i:06}");
        std::fs::copy(
            src.join(format!("depth/{stem}.png")),
            dir.join(format!("depth/{stem}.png")),
        )
        .unwrap();
        let mut pose = std::fs::read_to_string(src.join(format!("poses/{stem}.txt"))).unwrap();
        if n == 3 {
            pose = pose.replacen(pose.split_whitespace().next().unwrap(), "2.0", 1);
        }
        std::fs::write(dir.join(format!("poses/{stem}.txt")), pose).unwrap();
    }
    std::fs::copy(src.join("gravity.json"), dir.join("gravity.json")).unwrap();
    let camera = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("cameras/real-rgbd-2_sevenscenes_redkitchen.json");
    std::fs::copy(camera, dir.join("intrinsics.json")).unwrap();
}

/// Layer `name` in `out`: 200 × 200, its PNG decoding to its `.npy` by the stated scale and
/// offset (0: no data).
fn assert_png_is_npy(out: &Path, name: &str, layer: &serde_json::Value) {
    let (shape, values) = npy_f32(&out.join(format!("{name}.npy")));
    assert_eq!(shape, (200, 200), "{name}");
    let png = image::open(out.join(format!("{name}.png")))
        .unwrap()
        .to_luma16();
    let (scale, offset) = (
        layer["png_scale"].as_f64().unwrap(),
        layer["png_offset"].as_f64().unwrap(),
    );
    for (p, v) in png.as_raw().iter().zip(&values) {
        if *p == 0 {
            assert!(v.is_nan(), "{name}: {v}");
        } else {
            let decoded = offset + f64::from(p - 1) * scale;
            assert!(
                (decoded - f64::from(*v)).abs() <= scale * 0.5 + 1e-6,
                "{name}: {decoded} against {v}"
            );
        }
    }
}

#[test]
fn tre_map_writes_every_layer_and_skips_a_broken_pose() {
    let Some(kitchen) = shared_data("data/real-rgbd-2/sevenscenes_redkitchen") else {
        return;
    };
    let dir = tempfile::tempdir().unwrap();
    let seq = dir.path().join("seq");
    sequence(&kitchen, &seq);
    let out = dir.path().join("map");
    // A recording in a folder that does not exist yet: made, as `-o`'s is.
    let record = dir.path().join("recordings/run 1/map.mcap");
    assert!(!record.parent().unwrap().exists());
    let o = Command::new(env!("CARGO_BIN_EXE_tre"))
        .arg("map")
        .arg(&seq)
        .arg("-o")
        .arg(&out)
        .arg("--record")
        .arg(&record)
        .output()
        .unwrap();
    let (stdout, stderr) = (
        String::from_utf8_lossy(&o.stdout),
        String::from_utf8_lossy(&o.stderr),
    );
    assert!(o.status.success(), "{stderr}");
    assert!(stdout.starts_with("5 frames fused, 1 skipped"), "{stdout}");
    assert!(
        stderr.contains("skipped frame-000015") && stderr.contains("not a rigid transform"),
        "{stderr}"
    );
    let meta: serde_json::Value =
        serde_json::from_slice(&std::fs::read(out.join("map.json")).unwrap()).unwrap();
    assert_eq!(meta["cell_m"], 0.04);
    assert_eq!(meta["side_cells"], 200);
    assert_eq!(meta["frames_fused"], 5);
    for name in tre::map::LAYER_NAMES {
        assert_png_is_npy(&out, name, &meta["layers"][name]);
    }
    // Seen cells: a height, a count of at least one, and a three-state value.
    let (_, count) = npy_f32(&out.join("count.npy"));
    let (_, elevation) = npy_f32(&out.join("elevation.npy"));
    let seen = count.iter().filter(|&&c| c > 0.0).count();
    assert!(seen > 1000, "{seen} cells seen");
    assert!(count
        .iter()
        .zip(&elevation)
        .all(|(c, e)| (*c > 0.0) == e.is_finite()));
    assert!(out.join("layers.png").is_file());
    // The recording: the five fused frames, and the map equal to the layers written.
    assert!(stdout.contains("recorded "), "{stdout}");
    let map_dir = out.to_str().unwrap();
    check_mcap(
        &record,
        &["--kind", "map", "--frames", "5", "--map-dir", map_dir],
    );
}

/// `tre map` of a sequence that does not exist with the settings file `params`: the settings
/// are read first, so their error is the one said.
fn map_with_params(params: &Path, out: &Path) -> std::process::Output {
    Command::new(env!("CARGO_BIN_EXE_tre"))
        .args(["map", "no-such-sequence", "-o"])
        .arg(out)
        .arg("--params")
        .arg(params)
        .output()
        .unwrap()
}

#[test]
fn the_settings_files_are_the_presets_and_a_misspelt_key_is_refused() {
    use tre::io::map_params::read_map_params;
    use tre::map::{MapParams, MapPreset};
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("config/map");
    for (file, preset) in [
        ("indoor.toml", MapPreset::Indoor),
        ("outdoor.toml", MapPreset::Outdoor),
    ] {
        assert_eq!(
            read_map_params(&root.join(file)).unwrap(),
            MapParams::preset(preset),
            "{file}"
        );
    }
    let dir = tempfile::tempdir().unwrap();
    let bad = dir.path().join("bad.toml");
    std::fs::write(&bad, "preset = \"outdoor\"\n[grid]\ncel_m = 0.2\n").unwrap();
    let o = map_with_params(&bad, &dir.path().join("out"));
    let stderr = String::from_utf8_lossy(&o.stderr);
    assert!(!o.status.success());
    assert!(
        stderr.contains("bad.toml") && stderr.contains("cel_m") && stderr.contains("cell_m"),
        "{stderr}"
    );
    // A value out of range names its key.
    std::fs::write(&bad, "[traversability]\nmax_slope_deg = 95\n").unwrap();
    let o = map_with_params(&bad, &dir.path().join("out"));
    let stderr = String::from_utf8_lossy(&o.stderr);
    assert!(
        stderr.contains("traversability.max_slope_deg = 95"),
        "{stderr}"
    );
}
