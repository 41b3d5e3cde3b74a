//! Bytes per frame on the wire: the CDR size of every message the node publishes for one real
//! 640×480 kitchen depth frame (`real-rgbd-2/sevenscenes_redkitchen`, fused into the map with
//! its pose), with every image (the node's outputs before the images became opt-in), with the
//! defaults (the roughness alone, `32FC1`), and with `--roughness-encoding mono16`. The figures
//! are in docs/ros2.md; `cargo test -p tre-ros2 --test bytes_per_frame -- --nocapture` prints
//! them. Skipped when the shared data is missing (`TRE_SHARED_DIR`).
#![allow(clippy::unwrap_used, clippy::print_stderr)] // A test fails loudly and prints.

use std::path::PathBuf;

use tre_core::geometry::Vec3;
use tre_core::map::Pose;
use tre_record::encode::depth_mm_image;
use tre_record::msgs::{to_cdr, CameraInfo, Header, Time};
use tre_ros2::{FrameMsgs, ImageOutputs, MapSettings, Outputs, RoughnessEncoding};

mod common;

fn kitchen() -> Option<PathBuf> {
    let dir = common::kitchen_dir();
    // CI has the shared data (docs/testing.md): there a missing folder fails, not skips.
    if dir.is_none() && std::env::var("TRE_REQUIRE_SHARED").is_ok_and(|v| v == "1") {
        panic!("TRE_REQUIRE_SHARED=1 but the kitchen sequence is missing");
    }
    dir
}

fn frame(dir: &std::path::Path) -> FrameMsgs {
    let img = image::open(dir.join("depth/frame-000000.png"))
        .unwrap()
        .to_luma16();
    let (w, h) = img.dimensions();
    let header = Header::new(
        Time {
            sec: 1_700_000_000,
            nanosec: 0,
        },
        "camera_depth_optical_frame",
    );
    let depth = depth_mm_image(&header, &img);
    let info = CameraInfo {
        width: w,
        height: h,
        k: [585.0, 0.0, 320.0, 0.0, 585.0, 240.0, 0.0, 0.0, 1.0],
        ..CameraInfo::default()
    };
    let text = std::fs::read_to_string(dir.join("poses/frame-000000.txt")).unwrap();
    let v: Vec<f64> = text
        .split_whitespace()
        .map(|s| s.parse().unwrap())
        .collect();
    let pose = Pose {
        rotation: nalgebra::Matrix3::new(v[0], v[1], v[2], v[4], v[5], v[6], v[8], v[9], v[10]),
        translation: Vec3::new(v[3], v[7], v[11]),
    };
    FrameMsgs {
        depth: Some(depth),
        colour: None,
        info: Some(info),
        pose: Some(pose),
    }
}

/// The CDR bytes of each message published for the frame: (topic, bytes).
fn published(dir: &std::path::Path, images: ImageOutputs) -> Vec<(&'static str, usize)> {
    let mut p = common::kinect_processor(common::indoor_map(dir)).with_images(images);
    let o: Outputs = p.process(&frame(dir)).unwrap();
    assert!(o.map_error.is_none(), "{:?}", o.map_error);
    let mut sizes = vec![("roughness", to_cdr(&o.roughness).unwrap().len())];
    if let Some(u) = &o.uncertainty {
        sizes.push(("uncertainty", to_cdr(u).unwrap().len()));
    }
    if let Some(t) = &o.traversal {
        sizes.push(("traversal", to_cdr(t).unwrap().len()));
    }
    for (name, png) in &o.compressed {
        let topic = match *name {
            "roughness" => "roughness/compressed",
            "uncertainty" => "uncertainty/compressed",
            _ => "traversal/compressed",
        };
        sizes.push((topic, to_cdr(png).unwrap().len()));
    }
    sizes.push(("grid_map", to_cdr(o.grid.as_ref().unwrap()).unwrap().len()));
    sizes.push((
        "occupancy",
        to_cdr(o.occupancy.as_ref().unwrap()).unwrap().len(),
    ));
    sizes
}

fn total(sizes: &[(&str, usize)]) -> usize {
    sizes.iter().map(|(_, b)| b).sum()
}

#[test]
fn the_defaults_send_the_roughness_alone_and_mono16_halves_it() {
    let Some(dir) = kitchen() else { return };
    let all = published(&dir, ImageOutputs::all());
    let default = published(&dir, ImageOutputs::default());
    let mono16 = published(
        &dir,
        ImageOutputs {
            roughness: RoughnessEncoding::Mono16Mm,
            ..ImageOutputs::default()
        },
    );
    for (what, s) in [
        ("every image", &all),
        ("defaults", &default),
        ("mono16", &mono16),
    ] {
        eprintln!("{what}: {s:?}, total {} bytes", total(s));
    }
    let names = |s: &[(&'static str, usize)]| s.iter().map(|(n, _)| *n).collect::<Vec<_>>();
    assert_eq!(
        names(&all),
        [
            "roughness",
            "uncertainty",
            "traversal",
            "roughness/compressed",
            "uncertainty/compressed",
            "traversal/compressed",
            "grid_map",
            "occupancy"
        ]
    );
    assert_eq!(
        names(&default),
        ["roughness", "roughness/compressed", "grid_map", "occupancy"]
    );
    // 640×480 pixels: 4 bytes each as 32FC1, 2 as mono16, plus the header and encoding.
    let (r32, r16) = (default[0].1, mono16[0].1);
    assert!((4 * 640 * 480..4 * 640 * 480 + 200).contains(&r32), "{r32}");
    assert!((2 * 640 * 480..2 * 640 * 480 + 200).contains(&r16), "{r16}");
    assert_eq!(default[2..], all[6..], "the map's messages do not change");
    // The PNGs fit a stock Linux socket buffer (net.core.rmem_default, 208 KiB), which the raw
    // images do not.
    for (name, bytes) in all.iter().filter(|(n, _)| n.ends_with("/compressed")) {
        assert!(*bytes < 208 * 1024, "{name}: {bytes} bytes");
    }
    assert!(total(&default) + 4 * 640 * 480 < total(&all));
}

#[test]
fn the_grid_map_goes_out_once_a_grid_period_and_the_occupancy_grid_every_frame() {
    let Some(dir) = kitchen() else { return };
    let mut p = common::kinect_processor(MapSettings {
        grid_layers: vec!["elevation", "traversal"],
        grid_period: std::time::Duration::from_millis(200),
        ..common::indoor_map(&dir)
    });
    let mut f = frame(&dir);
    // Frames 0, 100, 200 and 250 ms apart from the first: grids at 0 and 200 ms only.
    let mut grids = Vec::new();
    for ms in [0, 100, 200, 250] {
        if let Some(d) = &mut f.depth {
            d.header.stamp = Time::from_nanos(1_700_000_000_000_000_000 + ms * 1_000_000);
        }
        let o = p.process(&f).unwrap();
        assert!(o.occupancy.is_some(), "an occupancy grid at {ms} ms");
        if let Some(g) = o.grid {
            assert_eq!(g.layers, ["elevation", "traversal"]);
            assert_eq!(g.data.len(), 2);
            grids.push(ms);
        }
    }
    assert_eq!(grids, [0, 200]);
}
