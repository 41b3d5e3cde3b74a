//! Synthetic dataset: determinism, depth and normals against the rendered geometry, and the
//! annotator on known scenes (flat pavement, stairs).
#![allow(clippy::unwrap_used)] // Test helpers fail loudly by design.

use std::path::Path;

use tre::geometry::{is_valid_point, Grid, Intrinsics, Mounting, Vec3};
use tre::roughness::{annotate, AnnotateConfig, AnnotateInput, Annotation};
use tre::synth::terrain::{Region, Steps};
use tre::synth::{
    render, Category, Conditions, HeightGrid, Lighting, RenderedFrame, Scene, SynthConfig, Terrain,
    View, Weather,
};

fn small_config(out: &Path, seed: u64) -> SynthConfig {
    SynthConfig {
        out: out.to_owned(),
        scenes: 2,
        seed,
        size: (64, 48),
        views: 3,
        ..SynthConfig::default()
    }
}

/// Every file under `dir`, relative path → bytes.
fn files(dir: &Path) -> Vec<(String, Vec<u8>)> {
    let mut out = Vec::new();
    let mut stack = vec![dir.to_owned()];
    while let Some(d) = stack.pop() {
        for e in std::fs::read_dir(&d).unwrap() {
            let p = e.unwrap().path();
            if p.is_dir() {
                stack.push(p);
            } else {
                out.push((
                    p.strip_prefix(dir).unwrap().display().to_string(),
                    std::fs::read(&p).unwrap(),
                ));
            }
        }
    }
    out.sort();
    out
}

#[test]
fn same_seed_same_bytes() {
    let (a, b, c) = (
        tempfile::tempdir().unwrap(),
        tempfile::tempdir().unwrap(),
        tempfile::tempdir().unwrap(),
    );
    tre::synth::generate(&small_config(a.path(), 5)).unwrap();
    tre::synth::generate(&small_config(b.path(), 5)).unwrap();
    tre::synth::generate(&small_config(c.path(), 6)).unwrap();
    let (fa, fb, fc) = (files(a.path()), files(b.path()), files(c.path()));
    assert_eq!(
        fa.len(),
        2 + 2 * 3 * 9,
        "{:?}",
        fa.iter().map(|f| &f.0).collect::<Vec<_>>()
    );
    for ((na, ba), (nb, bb)) in fa.iter().zip(&fb) {
        assert_eq!(na, nb);
        assert!(ba == bb, "{na} differs between two runs with the same seed");
    }
    let rgb = |f: &[(String, Vec<u8>)]| {
        f.iter()
            .find(|(n, _)| n.ends_with("view_0/rgb.png"))
            .unwrap()
            .1
            .clone()
    };
    assert_ne!(rgb(&fa), rgb(&fc), "another seed must give another scene");
}

fn robot_view(size: usize) -> View {
    View {
        mounting: Mounting::default(),
        yaw_rad: 0.0,
        intrinsics: Intrinsics::from_hfov(size, size, 60.0).unwrap(),
        width: size,
        height: size,
    }
}

fn scene_of(terrain: Terrain) -> Scene {
    let grid = HeightGrid::sample(&terrain, (-3.0, -0.8), (3.0, 3.0), 0.004);
    Scene { terrain, grid }
}

fn clear_noon() -> Conditions {
    Conditions {
        lighting: Lighting::HighSun,
        weather: Weather::Clear,
        sun_azimuth_rad: 0.5,
    }
}

fn annotate_frame(f: &RenderedFrame, view: &View) -> Annotation {
    let input = AnnotateInput {
        depth_m: &f.depth_m,
        intrinsics: &view.intrinsics,
        normals: Some(&f.normals_cam),
        labels: Some(&f.labels),
    };
    annotate(&input, &AnnotateConfig::default()).unwrap()
}

#[test]
fn depth_and_normals_agree_with_the_rendered_surface() {
    let cfg = SynthConfig {
        size: (160, 160),
        ..SynthConfig::default()
    };
    let views = tre::synth::dataset::scene_views(&cfg, 3);
    let scene = tre::synth::dataset::build_scene(&cfg, 3, &views);
    let (mut checked, mut worst_png_mm) = (0, 0.0f64);
    for view in [&views[0], &views[4], &views[8]] {
        let f = render(&scene, view, &clear_noon());
        let rot = view.world_from_cam();
        let png = tre::io::depth_png16(&f.depth_m);
        for v in 0..view.height {
            for u in 0..view.width {
                let d = f.depth_m[(u, v)];
                if d <= 0.0 {
                    continue;
                }
                let p = rot * view.intrinsics.back_project(u as f64, v as f64, d) + view.centre();
                let n = scene.grid.normal(p.x, p.y).unwrap();
                // On the surface: distance to the patch's tangent plane at (x, y).
                let dz = p.z - scene.grid.height(p.x, p.y).unwrap();
                assert!(
                    (dz * n.z).abs() < 1e-6,
                    "({u}, {v}): {dz} m off the surface"
                );
                let n_cam = f.normals_cam[(u, v)];
                let angle = (rot * n_cam).dot(&n).clamp(-1.0, 1.0).acos().to_degrees();
                assert!(angle < 1.0, "({u}, {v}): normal off by {angle}°");
                assert!(
                    n_cam.dot(&view.intrinsics.back_project(u as f64, v as f64, d)) < 0.0,
                    "faces the camera"
                );
                // The 16-bit millimetre PNG keeps points within 1 mm along the ray.
                let ray_m = view.intrinsics.back_project(u as f64, v as f64, 1.0).norm();
                let png_mm =
                    (f64::from(png.get_pixel(u as u32, v as u32)[0]) - d * 1000.0).abs() * ray_m;
                worst_png_mm = worst_png_mm.max(png_mm);
                checked += 1;
            }
        }
    }
    assert!(checked > 3 * 160 * 160 / 2, "{checked}");
    assert!(worst_png_mm <= 1.0, "{worst_png_mm} mm");
}

#[test]
fn flat_pavement_annotates_to_near_zero() {
    let view = robot_view(192);
    let f = render(
        &scene_of(Terrain::uniform(Category::Pavement, 1)),
        &view,
        &clear_noon(),
    );
    let ann = annotate_frame(&f, &view);
    let r: Vec<f64> = ann
        .roughness_m
        .as_slice()
        .iter()
        .copied()
        .filter(|r| r.is_finite())
        .collect();
    assert!(r.len() > 192 * 192 * 9 / 10);
    let max = r.iter().copied().fold(0.0, f64::max);
    assert!(max < 1e-4, "pavement roughness up to {max} m");
    assert!(f
        .labels
        .as_slice()
        .iter()
        .all(|&l| l == u32::from(Category::Pavement.label())));
}

#[test]
fn stairs_show_their_step_heights_on_the_boundaries() {
    // Three 10 cm steps descending away from the robot: each lip hides the tread beyond it, so
    // the 3-D gap across the boundary is at least the riser.
    let steps = Steps {
        dir: (0.0, -1.0),
        start_m: -1.6,
        tread_m: 0.35,
        riser_m: 0.10,
        steps: 3,
    };
    let terrain = Terrain {
        regions: vec![Region {
            centre: (0.0, 0.0),
            category: Category::Stairs,
            seed: 3,
            steps: Some(steps),
        }],
    };
    let view = robot_view(256);
    let f = render(&scene_of(terrain), &view, &clear_noon());
    let ann = annotate_frame(&f, &view);
    let rot = view.world_from_cam();
    // Boundary pixels on the near side of each lip (on a tread, within 2 cm of y = 0.9 or 1.25).
    let mut lips = [0usize; 2];
    for v in 0..256 {
        for u in 0..256 {
            if !ann.boundary[(u, v)] {
                continue;
            }
            let p = rot
                * view
                    .intrinsics
                    .back_project(u as f64, v as f64, f.depth_m[(u, v)])
                + view.centre();
            for (k, (lip_y, top)) in [(0.9, 0.3), (1.25, 0.2)].into_iter().enumerate() {
                if (p.y - lip_y).abs() < 0.02 && (p.z - top).abs() < 0.005 {
                    assert!(
                        ann.roughness_m[(u, v)] >= 0.10,
                        "lip {k} at ({u}, {v}): {}",
                        ann.roughness_m[(u, v)]
                    );
                    lips[k] += 1;
                }
            }
        }
    }
    assert!(
        lips.iter().all(|&n| n > 50),
        "boundary pixels on the lips: {lips:?}"
    );
    assert!(ann.segments.as_slice().iter().max().copied().unwrap_or(0) >= 3);
    let _ = (is_valid_point(&Vec3::zeros()), Grid::new(1, 1, 0u8));
}

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
