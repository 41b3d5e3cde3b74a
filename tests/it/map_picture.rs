//! `tre map`'s pictures for people on a small synthetic floor (a camera 1 m up, pitched 20°
//! from straight down, moving 0.75 m along x): `layers.png` and one `views/<layer>.png` per
//! layer, cropped to the seen floor (2.2 × 2.2 m, 0.2 m around it) rather than the 8 m window,
//! as `map.json`'s `picture` states and the pictures' sizes show.
#![allow(clippy::unwrap_used)] // Test helpers fail loudly by design.

use std::path::Path;
use std::process::Command;

use tre::geometry::Grid;

/// Camera intrinsics of the synthetic frames: 160 × 120 pixels, focal length 100.
const FX: f64 = 100.0;
const CX: f64 = 80.0;
const CY: f64 = 60.0;
/// The camera's pitch from straight down, radians.
const PITCH: f64 = 20.0 * std::f64::consts::PI / 180.0;

/// A sequence folder of four frames of a level floor 1 m below the camera, the camera moving
/// 0.25 m along +x between frames and looking along +x, 20° from straight down.
fn floor_sequence(dir: &Path) {
    for sub in ["depth", "poses"] {
        std::fs::create_dir_all(dir.join(sub)).unwrap();
    }
    let (s, c) = PITCH.sin_cos();
    // Depth along the optical axis of the floor at pixel row v (every column alike).
    let depth = Grid::from_fn(160, 120, |_, v| 1.0 / (s * (v as f64 + 0.5 - CY) / FX + c));
    for i in 0..4 {
        let stem = format!("frame-{i:06}");
        tre::io::write_npy_f32(&dir.join(format!("depth/{stem}.npy")), &depth).unwrap();
        // Camera to world, row by row: x → −y, y → (−c, 0, −s), optical axis → (s, 0, −c).
        let x = 0.25 * f64::from(i);
        let pose = format!("0 {} {s} {x}\n-1 0 0 0\n0 {} {} 1\n0 0 0 1\n", -c, -s, -c);
        std::fs::write(dir.join(format!("poses/{stem}.txt")), pose).unwrap();
    }
    std::fs::write(dir.join("gravity.json"), r#"{"gravity": [0, 0, -1]}"#).unwrap();
    let camera = serde_json::json!({
        "fx": FX, "fy": FX, "cx": CX, "cy": CY, "width": 160, "height": 120,
        "depth_scale": 1000.0, "sensor": "kinect_v1",
    });
    std::fs::write(dir.join("intrinsics.json"), camera.to_string()).unwrap();
}

/// Width and height of a PNG.
fn size(path: &Path) -> (u32, u32) {
    image::image_dimensions(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()))
}

#[test]
fn the_pictures_are_cropped_to_the_seen_floor_with_a_view_per_layer() {
    let dir = tempfile::tempdir().unwrap();
    let (seq, out) = (dir.path().join("seq"), dir.path().join("map"));
    floor_sequence(&seq);
    let o = Command::new(env!("CARGO_BIN_EXE_tre"))
        .arg("map")
        .arg(&seq)
        .arg("-o")
        .arg(&out)
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&o.stderr);
    assert!(o.status.success(), "{stderr}");
    let meta: serde_json::Value =
        serde_json::from_slice(&std::fs::read(out.join("map.json")).unwrap()).unwrap();
    let window_m = meta["cell_m"].as_f64().unwrap() * meta["side_cells"].as_f64().unwrap();
    let picture = &meta["picture"];
    let shown: Vec<f64> = (0..2)
        .map(|k| picture["shown_m"][k].as_f64().unwrap())
        .collect();
    // The floor seen: a trapezoid from 0.19 m behind the camera to 1.23 m ahead, 1.4 to 2.2 m
    // wide, swept 0.75 m along x: 2.17 × 2.18 m, and 0.2 m around it.
    assert!(window_m >= 8.0, "{window_m} m window");
    for m in &shown {
        assert!((2.4..2.8).contains(m), "{shown:?} m shown");
    }
    let px = picture["pixels_per_cell"].as_u64().unwrap() as u32;
    let cells = |k: usize| {
        let span = &picture[["columns", "rows"][k]];
        (span[1].as_u64().unwrap() - span[0].as_u64().unwrap()) as u32
    };
    let (map_w, map_h) = (cells(0) * px, cells(1) * px);
    assert!((300..=500).contains(&map_w.max(map_h)), "{map_w} × {map_h}");
    let sheet = size(&out.join("layers.png"));
    let layers = tre::map::LAYER_NAMES.len() as u32;
    assert!(sheet.0 * sheet.1 > layers * map_w * map_h, "{sheet:?}");
    assert!(sheet.0 * sheet.1 < 4 * layers * map_w * map_h, "{sheet:?}");
    for name in tre::map::LAYER_NAMES {
        let view = size(&out.join(format!("views/{name}.png")));
        assert!(view.0 > map_w && view.0 < map_w + 120, "{name}: {view:?}");
        assert!(view.1 > map_h && view.1 < map_h + 300, "{name}: {view:?}");
        // The data images stay as they were: the window's cells, 16-bit.
        let data = image::open(out.join(format!("{name}.png"))).unwrap();
        assert_eq!(data.color(), image::ColorType::L16, "{name}");
        assert_eq!(
            data.width() as f64 * meta["cell_m"].as_f64().unwrap(),
            window_m
        );
    }
}
