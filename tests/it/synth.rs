//! Synthetic dataset: determinism, depth and normals against the rendered geometry, and the
//! annotator on known scenes (flat pavement, stairs), the depth-sensor models (noise against
//! their presets, holes, realism against real Kinect floor), the indoor and urban content
//! (objects, labels, edges in the ground truth, natural output unchanged) and resumed runs.
#![allow(clippy::unwrap_used)] // Test helpers fail loudly by design.

use std::path::Path;

use tre::geometry::{is_valid_point, Grid, Intrinsics, Mounting, Vec3};
use tre::roughness::noise::SensorPreset;
use tre::roughness::{annotate, AnnotateConfig, AnnotateInput, Annotation};
use tre::synth::imaging::ImageEffect;
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
        sensors: SensorPreset::ALL.to_vec(),
        effects: ImageEffect::ALL.to_vec(),
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
        2 + 2 * 3 * 10,
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
        roll_rad: 0.0,
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
fn a_rolled_camera_sees_the_ground_where_its_recorded_pose_puts_it() {
    // Flat pavement (height 0) seen with 8° of roll: every rendered point, taken to the world
    // frame with the view's own pose, lies on the ground plane, and the image differs from the
    // level camera's.
    let scene = scene_of(Terrain::uniform(Category::Pavement, 1));
    let level = robot_view(96);
    let rolled = View {
        roll_rad: 8f64.to_radians(),
        ..level
    };
    let (a, b) = (
        render(&scene, &level, &clear_noon()),
        render(&scene, &rolled, &clear_noon()),
    );
    let points = rolled.intrinsics.back_project_map(&b.depth_m);
    let (r, c) = (rolled.world_from_cam(), rolled.centre());
    let mut on_ground = 0;
    for p in points.as_slice().iter().filter(|p| is_valid_point(p)) {
        let z = (r * p + c).z;
        assert!(z.abs() < 1e-6, "a point {z} m off the ground");
        on_ground += 1;
    }
    assert!(on_ground > 96 * 96 / 2, "{on_ground}");
    let moved = a
        .depth_m
        .as_slice()
        .iter()
        .zip(b.depth_m.as_slice())
        .filter(|(x, y)| (*x - *y).abs() > 1e-3)
        .count();
    assert!(moved > 96 * 96 / 4, "roll moved only {moved} pixels");
}

#[test]
fn random_optics_draw_every_frame_within_the_documented_ranges() {
    use tre::synth::dataset::OPTICS;
    let dir = tempfile::tempdir().unwrap();
    let cfg = SynthConfig {
        out: dir.path().to_owned(),
        scenes: 2,
        seed: 11,
        size: (96, 72),
        ply: false,
        random_optics: true,
        ..SynthConfig::default()
    };
    tre::synth::generate(&cfg).unwrap();
    let within = |(lo, hi): (f64, f64), v: f64| v >= lo - 1e-9 && v <= hi + 1e-9;
    let (mut shapes, mut pitches, mut rolls) = (Vec::new(), Vec::new(), Vec::new());
    for s in 0..2 {
        for v in 0..9 {
            let dir = dir.path().join(format!("scene_{s:05}/view_{v}"));
            let cam: serde_json::Value =
                serde_json::from_slice(&std::fs::read(dir.join("camera.json")).unwrap()).unwrap();
            let num = |k: &str| cam[k].as_f64().unwrap_or(0.0);
            let (w, h) = (num("width"), num("height"));
            assert_eq!(w, 96.0);
            let depth = image::open(dir.join("depth.png")).unwrap();
            assert_eq!((depth.width() as f64, depth.height() as f64), (w, h));
            let hfov = 2.0 * (w / 2.0 / num("fx")).atan().to_degrees();
            assert!(within(OPTICS.hfov_deg, hfov), "hfov {hfov}");
            assert!(within(OPTICS.pitch_deg, num("pitch_deg")));
            assert!(within(OPTICS.height_m, num("height_m")));
            assert!(within(OPTICS.roll_deg, num("roll_deg")));
            shapes.push(h as usize);
            pitches.push(num("pitch_deg"));
            rolls.push(num("roll_deg"));
        }
    }
    shapes.sort_unstable();
    shapes.dedup();
    // 4:3, 16:9 and 1242:375 of a 96-pixel width, rounded to even heights.
    assert_eq!(shapes, vec![28, 54, 72]);
    assert!(rolls.iter().any(|&r| r < -1.0) && rolls.iter().any(|&r| r > 1.0));
    assert!(pitches.iter().any(|&p| p < 30.0) && pitches.iter().any(|&p| p > 60.0));
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
        ..Terrain::default()
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

mod sensors {
    //! Depth-sensor models on analytic planes and steps, and against real Kinect floor.

    use super::*;
    use image::RgbImage;
    use tre::geometry::hash::uniform;
    use tre::synth::sensor::{simulate, SensorInput, SensorModel};

    /// A textured grey image (values 60–200, per-pixel hash).
    fn textured(w: usize, h: usize) -> RgbImage {
        RgbImage::from_fn(w as u32, h as u32, |x, y| {
            let v = (60.0 + 140.0 * uniform(9, u64::from(y) << 16 | u64::from(x), 0, 0)) as u8;
            image::Rgb([v; 3])
        })
    }

    /// Fronto-parallel planes: depth `z_of(x)` per column, normals facing the camera.
    fn columns(w: usize, h: usize, z_of: impl Fn(usize) -> f64) -> (Grid<f64>, Grid<Vec3>) {
        (
            Grid::from_fn(w, h, |x, _| z_of(x)),
            Grid::new(w, h, Vec3::new(0.0, 0.0, -1.0)),
        )
    }

    fn run(sensor: SensorPreset, depth: &Grid<f64>, normals: &Grid<Vec3>, f: f64) -> Grid<f64> {
        let (w, h) = depth.size();
        let k = Intrinsics::new(f, f, w as f64 / 2.0, h as f64 / 2.0).unwrap();
        let rgb = textured(w, h);
        let input = SensorInput {
            depth_m: depth,
            normals_cam: normals,
            rgb: &rgb,
            intrinsics: &k,
        };
        simulate(&SensorModel::preset(sensor), &input, 42)
    }

    /// Standard deviation of the error (along the optical axis, or along the ray for time of
    /// flight and LiDAR) over valid pixels, and the share of valid pixels.
    fn error_sd(sensor: SensorPreset, z: f64, f: f64) -> (f64, f64) {
        let (w, h) = (320, 240);
        let (depth, normals) = columns(w, h, |_| z);
        let out = run(sensor, &depth, &normals, f);
        let along_ray = matches!(sensor, SensorPreset::AzureKinect | SensorPreset::Lidar);
        let errs: Vec<f64> = (0..h)
            .flat_map(|y| (0..w).map(move |x| (x, y)))
            .filter(|&p| out[p] > 0.0)
            .map(|(x, y)| {
                let ray = if along_ray {
                    let (u, v) = (
                        (x as f64 - w as f64 / 2.0) / f,
                        (y as f64 - h as f64 / 2.0) / f,
                    );
                    (1.0 + u * u + v * v).sqrt()
                } else {
                    1.0
                };
                (out[(x, y)] - z) * ray
            })
            .collect();
        let n = errs.len() as f64;
        let mean = errs.iter().sum::<f64>() / n;
        let sd = (errs.iter().map(|e| (e - mean).powi(2)).sum::<f64>() / n).sqrt();
        (sd, n / (w * h) as f64)
    }

    #[test]
    fn flat_plane_error_has_the_preset_sigma_within_10_percent() {
        let cases = [
            (SensorPreset::KinectV1, [1.0, 2.0, 3.0]),
            (SensorPreset::RealsenseD435, [1.0, 2.0, 3.0]),
            (SensorPreset::AzureKinect, [1.0, 2.0, 3.0]),
            (SensorPreset::Lidar, [2.0, 5.0, 10.0]),
        ];
        for (sensor, ranges) in cases {
            for z in ranges {
                let (sd, valid) = error_sd(sensor, z, 300.0);
                let want = sensor.sigma_z_m(z);
                eprintln!(
                    "{sensor} {z} m: sd {:.2} mm, preset {:.2} mm, valid {valid:.3}",
                    sd * 1e3,
                    want * 1e3
                );
                assert!(
                    (sd / want - 1.0).abs() < 0.10,
                    "{sensor} at {z} m: sd {sd}, preset {want}"
                );
                assert!(valid > 0.02, "{sensor} at {z} m: {valid} valid");
            }
        }
        let (sd, valid) = error_sd(SensorPreset::Exact, 2.0, 300.0);
        assert!(sd == 0.0 && valid == 1.0);
        // Out of range: a Kinect v1 sees nothing at 5 m, a D435 nothing at 0.15 m.
        assert_eq!(error_sd(SensorPreset::KinectV1, 5.0, 300.0).1, 0.0);
        assert_eq!(error_sd(SensorPreset::RealsenseD435, 0.15, 300.0).1, 0.0);
    }

    #[test]
    fn lidar_returns_are_a_sparse_ring_pattern() {
        let (depth, normals) = columns(320, 240, |_| 5.0);
        let out = run(SensorPreset::Lidar, &depth, &normals, 300.0);
        // Near the centre column each of the 64 rings crosses one row (they bend at the sides).
        let rows_hit = (0..240)
            .filter(|&y| (158..163).any(|x| out[(x, y)] > 0.0))
            .count();
        let valid = out.as_slice().iter().filter(|&&z| z > 0.0).count();
        assert!((60..=68).contains(&rows_hit), "{rows_hit} rows");
        assert!(valid > 64 * 200 && valid < 320 * 240 / 2, "{valid} returns");
    }

    /// A box face at 1.5 m over columns [140, 220) in front of a wall at 2 m.
    fn step_scene() -> (Grid<f64>, Grid<Vec3>) {
        columns(
            320,
            240,
            |x| if (140..220).contains(&x) { 1.5 } else { 2.0 },
        )
    }

    #[test]
    fn structured_light_shadow_lies_left_of_the_nearer_surface() {
        let (depth, normals) = step_scene();
        let out = run(SensorPreset::KinectV1, &depth, &normals, 600.0);
        // The projector 75 mm to the right misses f·b·(1/1.5 − 1/2) = 7.5 px left of the box.
        let hole = |x: usize| (0..240).all(|y| out[(x, y)] == 0.0);
        assert!((133..140).all(hole), "shadow band");
        let valid_share = |xs: std::ops::Range<usize>| {
            let n = xs.len() * 240;
            xs.flat_map(|x| (0..240).map(move |y| (x, y)))
                .filter(|&p| out[p] > 0.0)
                .count() as f64
                / n as f64
        };
        assert!(valid_share(120..131) > 0.99, "left of the shadow");
        assert!(
            valid_share(140..240) > 0.99,
            "box and its right side: no shadow"
        );
    }

    #[test]
    fn time_of_flight_flies_and_drops_at_depth_edges_only() {
        let (depth, normals) = step_scene();
        let out = run(SensorPreset::AzureKinect, &depth, &normals, 300.0);
        let edge: [usize; 4] = [139, 140, 219, 220];
        let (mut holes, mut mixed, mut n) = (0, 0, 0);
        for x in edge {
            for y in 0..240 {
                n += 1;
                let z = out[(x, y)];
                if z == 0.0 {
                    holes += 1;
                } else if z > 1.56 && z < 1.94 {
                    mixed += 1;
                }
            }
        }
        assert!(
            holes > n / 4 && mixed > n / 8,
            "{holes} holes, {mixed} mixed of {n}"
        );
        let away = (0..320)
            .filter(|x: &usize| edge.iter().all(|e| x.abs_diff(*e) > 2))
            .flat_map(|x| (0..240).map(move |y| (x, y)));
        assert!(away.clone().all(|p| out[p] > 0.0), "holes away from edges");
    }

    #[test]
    fn active_stereo_has_its_left_band_and_fattens_edges() {
        let (depth, normals) = step_scene();
        let out = run(SensorPreset::RealsenseD435, &depth, &normals, 300.0);
        // Invalid band: x < f·b/z = 300·0.05/2 = 7.5 px.
        assert!((0..240).all(|y| (0..8).all(|x| out[(x, y)] == 0.0)));
        // Fattening: the wall just right of the box reads the box's depth (3 native px ≈ 2 px).
        let fat = (0..240)
            .filter(|&y| (out[(221, y)] - 1.5).abs() < 0.1)
            .count();
        assert!(fat > 200, "{fat} rows fattened");
        assert!((0..240).all(|y| (out[(230, y)] - 2.0).abs() < 0.1));
    }

    #[test]
    fn same_seed_same_depth_and_the_exact_frame_is_untouched() {
        let (depth, normals) = step_scene();
        for s in SensorPreset::ALL {
            assert!(run(s, &depth, &normals, 300.0) == run(s, &depth, &normals, 300.0));
        }
        let (a, b) = (tempfile::tempdir().unwrap(), tempfile::tempdir().unwrap());
        let cfg = |out: &Path, sensor| SynthConfig {
            sensors: vec![sensor],
            ply: false,
            ..small_config(out, 3)
        };
        tre::synth::generate(&cfg(a.path(), SensorPreset::Exact)).unwrap();
        tre::synth::generate(&cfg(b.path(), SensorPreset::KinectV1)).unwrap();
        let (fa, fb) = (files(a.path()), files(b.path()));
        let mut sensor_differs = 0;
        for ((na, ba), (nb, bb)) in fa.iter().zip(&fb) {
            assert_eq!(na, nb);
            if na.ends_with("depth_sensor.png") {
                sensor_differs += usize::from(ba != bb);
            } else if !na.ends_with("camera.json") && !na.ends_with("dataset.json") {
                assert!(ba == bb, "{na} changed with the sensor");
            }
        }
        assert_eq!(sensor_differs, 2 * 3);
        let cam: serde_json::Value =
            serde_json::from_slice(&fb.iter().find(|f| f.0.ends_with("camera.json")).unwrap().1)
                .unwrap();
        assert_eq!(cam["sensor"], "kinect_v1");
        assert_eq!(cam["sensor_model"]["baseline_m"], 0.075);
        // The exact sensor writes the exact depth.
        let exact = |suffix: &str| {
            fa.iter()
                .find(|f| f.0.ends_with(&format!("view_0/{suffix}")))
                .unwrap()
                .1
                .clone()
        };
        assert!(exact("depth.png") == exact("depth_sensor.png"));
    }
}

mod realism {
    //! The Kinect model's spec roughness on synthetic flat floor against real Kinect floor.

    use super::*;
    use std::path::PathBuf;
    use tre::io::sheet::{
        colour_bar_legend, contact_sheet, depth_panel, fit_within, roughness_panel, Panel,
    };
    use tre::synth::sensor::{simulate, SensorInput, SensorModel};

    /// Range bins (depth, metres) centred on 2, 2.5 and 3 m: the real floor boxes lie at
    /// 1.4–3.0 m (71 of their pixels nearer than 1.2 m), so 1 m cannot be compared.
    const BINS: [(f64, f64); 3] = [(1.75, 2.25), (2.25, 2.75), (2.75, 3.25)];

    fn bin_of(z: f64) -> Option<usize> {
        BINS.iter().position(|&(a, b)| z >= a && z < b)
    }

    fn median(mut v: Vec<f64>) -> f64 {
        if v.is_empty() {
            return f64::NAN;
        }
        v.sort_by(f64::total_cmp);
        v[v.len() / 2]
    }

    fn spec(depth: &Grid<f64>, k: &Intrinsics) -> Annotation {
        let input = AnnotateInput {
            depth_m: depth,
            intrinsics: k,
            normals: None,
            labels: None,
        };
        annotate(&input, &AnnotateConfig::default()).unwrap()
    }

    #[derive(serde::Deserialize)]
    struct Fixture {
        frames: Vec<RealFloor>,
    }

    #[derive(serde::Deserialize)]
    struct RealFloor {
        dir: String,
        depth: String,
        floor: [usize; 4],
    }

    fn real_data() -> PathBuf {
        Path::new(env!("CARGO_MANIFEST_DIR")).join("../shared/data/real-rgbd")
    }

    /// Spec roughness of the real floor boxes' pixels, by range bin.
    fn real_floor() -> [Vec<f64>; 3] {
        let fixture = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/fixtures/real_floor.json");
        let fx: Fixture = serde_json::from_slice(&std::fs::read(fixture).unwrap()).unwrap();
        let mut bins: [Vec<f64>; 3] = Default::default();
        for f in &fx.frames {
            let dir = real_data().join(&f.dir);
            let (cam, k) = tre::io::read_camera(&dir.join("intrinsics.json")).unwrap();
            let depth = tre::io::read_depth(&dir.join(&f.depth), cam.depth_scale.unwrap()).unwrap();
            let r = spec(&depth, &k).roughness_m;
            let [x0, y0, x1, y1] = f.floor;
            for (x, y) in (y0..y1).flat_map(|y| (x0..x1).map(move |x| (x, y))) {
                if let (Some(b), true) = (bin_of(depth[(x, y)]), r[(x, y)].is_finite()) {
                    bins[b].push(r[(x, y)]);
                }
            }
        }
        bins
    }

    /// A flat floor seen by a 640×480 Kinect-like camera (f = 525 px) mounted as the real
    /// frames are (their floor planes lie 1.3–1.55 m below the camera; floor at 2 m depth in
    /// the bottom rows): 1.45 m up, pitched 22° down. Returns the frame, its view and the
    /// sensor depth.
    fn synthetic_floor(model: &SensorModel, seed: u64) -> (RenderedFrame, View, Grid<f64>) {
        let view = View {
            mounting: Mounting::new(22f64.to_radians(), 1.45).unwrap(),
            yaw_rad: 0.0,
            roll_rad: 0.0,
            intrinsics: Intrinsics::new(525.0, 525.0, 319.5, 239.5).unwrap(),
            width: 640,
            height: 480,
        };
        let terrain = Terrain::uniform(Category::Pavement, 1);
        let grid = HeightGrid::sample(&terrain, (-4.5, -0.8), (4.5, 6.0), 0.01);
        let f = render(&Scene { terrain, grid }, &view, &clear_noon());
        let input = SensorInput {
            depth_m: &f.depth_m,
            normals_cam: &f.normals_cam,
            rgb: &f.rgb,
            intrinsics: &view.intrinsics,
        };
        let d = simulate(model, &input, seed);
        (f, view, d)
    }

    /// Spec roughness of the synthetic floor's interior pixels by range bin, with the frame,
    /// its sensor depth and roughness map.
    fn synthetic_bins(model: &SensorModel) -> ([Vec<f64>; 3], RenderedFrame, Grid<f64>, Grid<f64>) {
        let (frame, view, sensor) = synthetic_floor(model, 7);
        let rough = spec(&sensor, &view.intrinsics).roughness_m;
        let mut syn: [Vec<f64>; 3] = Default::default();
        for y in 8..472 {
            for x in 8..632 {
                let r = rough[(x, y)];
                if let (Some(b), true) = (bin_of(sensor[(x, y)]), r.is_finite()) {
                    syn[b].push(r);
                }
            }
        }
        (syn, frame, sensor, rough)
    }

    #[test]
    fn kinect_floor_roughness_median_within_30_percent_of_real_floor() {
        let real = real_floor();
        let kinect = SensorModel::preset(SensorPreset::KinectV1);
        let (syn, frame, sensor, rough) = synthetic_bins(&kinect);
        // The same noise drawn independently per pixel, for comparison (not asserted).
        let white = SensorModel {
            correlated_share: 0.0,
            ..kinect
        };
        let (syn_white, ..) = synthetic_bins(&white);
        let mut compared = 0;
        for (b, (lo, hi)) in BINS.iter().enumerate() {
            let m_real = median(real[b].clone());
            let (m_syn, m_white) = (median(syn[b].clone()), median(syn_white[b].clone()));
            eprintln!(
                "| {lo}–{hi} | {} | {:.3} | {} | {:.3} | {:.2} | {:.3} | {:.2} |",
                real[b].len(),
                m_real * 100.0,
                syn[b].len(),
                m_syn * 100.0,
                m_syn / m_real,
                m_white * 100.0,
                m_white / m_real
            );
            if real[b].len() >= 500 {
                compared += 1;
                assert!((m_syn / m_real - 1.0).abs() < 0.3, "bin {lo}–{hi} m");
            }
        }
        assert!(
            compared >= 2,
            "real floor pixels by bin: {:?}",
            real.map(|v| v.len())
        );
        if let Ok(out) = std::env::var("TRE_SYNTH_SHEET") {
            write_sheet(Path::new(&out), &frame, &sensor, &rough);
        }
    }

    /// Synthetic and real frame side by side: RGB, sensor depth, spec roughness (0–5 cm).
    fn write_sheet(out: &Path, f: &RenderedFrame, sensor: &Grid<f64>, rough: &Grid<f64>) {
        let dir = real_data().join("slambook2_ch5");
        let (cam, k) = tre::io::read_camera(&dir.join("intrinsics.json")).unwrap();
        let depth =
            tre::io::read_depth(&dir.join("depth/1.png"), cam.depth_scale.unwrap()).unwrap();
        let real_rgb = tre::io::read_image(&dir.join("color/1.png"))
            .unwrap()
            .to_rgb8();
        let real_rough = spec(&depth, &k).roughness_m;
        let fit = |img: image::RgbImage| fit_within(&img, 256, 192);
        let panels = vec![
            Panel::new("synthetic RGB", fit(f.rgb.clone())),
            Panel::new("kinect_v1 model depth", fit(depth_panel(sensor, 5.0))),
            Panel::new("spec roughness", fit(roughness_panel(rough, 0.05))),
            Panel::new("real Kinect RGB", fit(real_rgb)),
            Panel::new("real Kinect depth", fit(depth_panel(&depth, 5.0))),
            Panel::new("spec roughness", fit(roughness_panel(&real_rough, 0.05))),
        ];
        let legend = colour_bar_legend(480, 0.05, &[0.0, 1.0, 2.0, 3.0, 4.0, 5.0]);
        let sheet = contact_sheet(&panels, 3, Some(&legend));
        tre::io::save(out, &image::DynamicImage::ImageRgb8(sheet)).unwrap();
    }
}

/// RMSE (cm) printed by `tre eval --mode geometric` on `data`'s split with `--depth-source`.
fn eval_rmse(data: &Path, split: &str, source: &str) -> f64 {
    let out = std::process::Command::new(env!("CARGO_BIN_EXE_tre"))
        .args([
            "eval",
            "--data",
            data.to_str().unwrap(),
            "--mode",
            "geometric",
        ])
        .args(["--split", split, "--depth-source", source])
        .output()
        .unwrap();
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    text.split("RMSE ")
        .nth(1)
        .unwrap()
        .split(' ')
        .next()
        .unwrap()
        .parse()
        .unwrap()
}

#[test]
fn eval_reads_sensor_depth_against_exact_ground_truth() {
    let dir = tempfile::tempdir().unwrap();
    let cfg = SynthConfig {
        out: dir.path().to_owned(),
        scenes: 2,
        seed: 4,
        size: (128, 96),
        views: 2,
        ply: false,
        test_fraction: 0.0,
        sensors: vec![SensorPreset::KinectV1],
        ..SynthConfig::default()
    };
    tre::synth::generate(&cfg).unwrap();
    let exact = eval_rmse(dir.path(), "train", "exact");
    let sensor = eval_rmse(dir.path(), "train", "sensor");
    // Kinect noise and holes make the spec on sensor depth differ more from the exact truth.
    assert!(
        sensor > exact + 0.05,
        "exact {exact} cm, sensor {sensor} cm"
    );
}

#[test]
fn image_effects_change_only_the_image_and_are_recorded() {
    let (a, b) = (tempfile::tempdir().unwrap(), tempfile::tempdir().unwrap());
    let cfg = |out: &Path, effects: Vec<ImageEffect>| SynthConfig {
        effects,
        sensors: vec![SensorPreset::KinectV1],
        ply: false,
        ..small_config(out, 8)
    };
    tre::synth::generate(&cfg(a.path(), vec![])).unwrap();
    tre::synth::generate(&cfg(b.path(), ImageEffect::ALL.to_vec())).unwrap();
    let (fa, fb) = (files(a.path()), files(b.path()));
    let mut rgb_differs = 0;
    for ((na, ba), (_, bb)) in fa.iter().zip(&fb) {
        if na.ends_with("rgb.png") {
            rgb_differs += usize::from(ba != bb);
        } else if !na.ends_with(".json") && !na.ends_with("contact_sheet.png") {
            // Depth, sensor depth (drawn from the clean render), labels and ground truth.
            assert!(ba == bb, "{na} changed with the image effects");
        }
    }
    assert_eq!(rgb_differs, 2 * 3);
    let cam: serde_json::Value =
        serde_json::from_slice(&fb.iter().find(|f| f.0.ends_with("camera.json")).unwrap().1)
            .unwrap();
    let im = &cam["imaging"];
    assert_eq!(im["effects"].as_array().unwrap().len(), 7);
    let q = im["jpeg_quality"].as_u64().unwrap();
    assert!((40..=95).contains(&q), "{im}");
    assert!(im["exposure_stops"].as_f64().unwrap().abs() <= 1.0);
}

mod content {
    //! Indoor and urban content: object profiles, layouts, labels in the frames, the spec's edges
    //! on curbs, sills and boxes, natural output unchanged, and resumed runs.

    use super::*;
    use sha2::{Digest, Sha256};
    use std::collections::BTreeSet;
    use tre::synth::content::{indoor, urban, Content};
    use tre::synth::objects::{Object, Profile, Shape};

    fn object(category: Category, shape: Shape, profile: Profile) -> Object {
        Object {
            category,
            seed: 1,
            shape,
            profile,
        }
    }

    #[test]
    fn profiles_give_their_heights() {
        let rect = Shape::rect((0.0, 2.0), (0.5, 0.4), 0.0);
        let flight = Profile::Flight {
            base_m: 0.0,
            riser_m: -0.15,
            tread_m: 0.3,
            steps: 3,
        };
        let flight = object(Category::Stairs, rect.clone(), flight);
        // u from −0.5: first tread to −0.2, second to 0.1, then the third and the landing.
        for (x, want) in [(-0.4, -0.15), (0.0, -0.30), (0.3, -0.45), (0.49, -0.45)] {
            assert!((flight.height_over(x, 2.0, 0.0, 0.0).unwrap() - want).abs() < 1e-12);
        }
        assert!(flight.height_over(0.6, 2.0, 0.0, 0.0).is_none());
        let ramp = Profile::Ramp {
            low_m: -0.12,
            high_m: 0.0,
            flare_m: 0.1,
        };
        let ramp = object(Category::KerbRamp, rect, ramp);
        assert!((ramp.height_over(-0.5, 2.0, 0.0, 0.0).unwrap() + 0.12).abs() < 1e-12);
        assert!((ramp.height_over(0.0, 2.0, 0.0, 0.0).unwrap() + 0.06).abs() < 1e-12);
        assert!(ramp.height_over(-0.5, 2.4, 0.0, 0.0).unwrap().abs() < 1e-12); // flared side
        let path = Shape::Path {
            points: vec![(0.0, 0.0), (1.0, 0.0)],
            radius_m: 0.005,
        };
        let cable = object(Category::Cable, path, Profile::Round);
        assert!((cable.height_over(0.5, 0.0, 0.0, 0.0).unwrap() - 0.01).abs() < 1e-12);
        assert!((cable.height_over(0.5, 0.0, 0.008, 0.0).unwrap() - 0.018).abs() < 1e-12);
        assert!(cable.height_over(0.5, 0.006, 0.0, 0.0).is_none());
        let drain = Profile::Grate {
            top_m: 0.0,
            recess_m: 0.015,
            frame_m: 0.03,
            slot_m: 0.02,
            pitch_m: 0.04,
            slot_depth_m: 0.05,
        };
        let drain = object(
            Category::Drain,
            Shape::rect((0.0, 0.0), (0.2, 0.15), 0.3),
            drain,
        );
        let (s, c) = 0.3f64.sin_cos();
        let at = |u: f64, v: f64| {
            drain
                .height_over(u * c - v * s, u * s + v * c, 0.0, 0.0)
                .unwrap()
        };
        assert_eq!(at(-0.19, 0.0), 0.0); // frame
        assert!((at(-0.16, 0.0) + 0.065).abs() < 1e-9); // slot, 1 cm past the frame
        assert!((at(-0.145, 0.0) + 0.015).abs() < 1e-9); // bar
                                                         // Outlines blend over the edge width: half the top on the outline, all of it half an
                                                         // edge inside, nothing half an edge outside.
        let block = Shape::rect((0.0, 0.0), (0.2, 0.1), 0.3);
        let block = object(Category::Box, block, Profile::Block { top_m: 0.3 });
        let on = |u: f64| block.height_over(u * c, u * s, 0.0, 0.004);
        assert!((on(0.2).unwrap() - 0.15).abs() < 1e-9);
        assert!((on(0.198).unwrap() - 0.3).abs() < 1e-9);
        assert!(on(0.2021).is_none());
    }

    #[test]
    fn names_round_trip_and_mixed_draws_every_family() {
        for c in Content::ALL {
            assert_eq!(c.name().parse(), Ok(c));
            assert_eq!(serde_json::to_string(&c).unwrap(), format!("\"{c}\""));
        }
        let families: BTreeSet<String> = (0..30)
            .map(|s| Content::Mixed.family(7, s).to_string())
            .collect();
        assert_eq!(families.len(), 3);
        assert_eq!(Content::Urban.family(7, 3), Content::Urban);
        let labels: BTreeSet<u8> = Category::ALL.iter().map(|c| c.label()).collect();
        assert_eq!(labels, (1..=20).collect(), "labels 1–20, each once");
    }

    #[test]
    fn layouts_hold_every_object_of_their_family_and_repeat() {
        for scene in 0..40 {
            for reach in [2.2, 4.0] {
                for (family, want) in [
                    (Content::Indoor, &Category::INDOOR[..]),
                    (Content::Urban, &Category::URBAN[..]),
                ] {
                    let terrain = family.terrain(3, scene, reach);
                    let have: Vec<Category> = terrain.objects.iter().map(|o| o.category).collect();
                    for c in want {
                        // A slab sidewalk (pavement) stands in for block paving in some scenes.
                        let alt = *c == Category::Paving && have.contains(&Category::Pavement);
                        assert!(
                            have.contains(c) || alt,
                            "scene {scene}: no {c:?} in {have:?}"
                        );
                    }
                    assert_eq!(terrain, family.terrain(3, scene, reach));
                }
            }
        }
        assert_ne!(indoor(3, 0, 2.2), indoor(4, 0, 2.2));
        assert_ne!(urban(3, 0, 2.2), urban(3, 1, 2.2));
    }
    /// SHA-256 over the names and bytes of every file of `dir` but the JSON ones.
    fn digest_without_json(dir: &Path) -> (usize, String) {
        let mut h = Sha256::new();
        let mut n = 0;
        for (name, bytes) in files(dir) {
            if !name.ends_with(".json") {
                h.update(name.as_bytes());
                h.update(&bytes);
                n += 1;
            }
        }
        (n, format!("{:x}", h.finalize()))
    }

    #[test]
    fn natural_output_is_unchanged() {
        // Recorded with the generator before indoor and urban content existed (x86-64 Linux):
        // `tre synth --out D --scenes 2 --width 160 --height 120 --views 3 --seed 5`, every file
        // but the JSON ones (images, depth, labels, normals, ground truth, PLY, contact sheet).
        let dir = tempfile::tempdir().unwrap();
        let cfg = SynthConfig {
            out: dir.path().to_owned(),
            scenes: 2,
            seed: 5,
            size: (160, 120),
            views: 3,
            ..SynthConfig::default()
        };
        tre::synth::generate(&cfg).unwrap();
        assert_eq!(
            digest_without_json(dir.path()),
            (
                55,
                "106dae2251fd0958a5cc1995bf4a65864c138ad0b8ba6dfaddd3017594ea8420".to_string()
            )
        );
        // The manifest names no content and lists the six natural labels, as before.
        let text = std::fs::read_to_string(dir.path().join("dataset.json")).unwrap();
        assert!(!text.contains("content"), "{text}");
        let m: serde_json::Value = serde_json::from_str(&text).unwrap();
        assert_eq!(m["labels"].as_array().unwrap().len(), 6);
    }

    #[test]
    fn indoor_urban_and_mixed_same_seed_same_bytes() {
        for content in [Content::Indoor, Content::Urban, Content::Mixed] {
            let (a, b) = (tempfile::tempdir().unwrap(), tempfile::tempdir().unwrap());
            let cfg = |out: &Path| SynthConfig {
                content,
                ply: false,
                ..small_config(out, 21)
            };
            tre::synth::generate(&cfg(a.path())).unwrap();
            tre::synth::generate(&cfg(b.path())).unwrap();
            let (fa, fb) = (files(a.path()), files(b.path()));
            assert_eq!(fa.len(), 2 + 2 * 3 * 9, "{content}");
            for ((na, ba), (nb, bb)) in fa.iter().zip(&fb) {
                assert_eq!(na, nb);
                assert!(ba == bb, "{content}: {na} differs between two runs");
            }
            let m: serde_json::Value =
                serde_json::from_slice(&fa.iter().find(|f| f.0 == "dataset.json").unwrap().1)
                    .unwrap();
            assert_eq!(m["config"]["content"], content.name());
            assert_eq!(m["labels"].as_array().unwrap().len(), 20);
        }
    }

    /// Labels seen in the frames of scene 0 of a dataset of `content`.
    fn labels_seen(content: Content, seed: u64) -> BTreeSet<u8> {
        let dir = tempfile::tempdir().unwrap();
        let cfg = SynthConfig {
            out: dir.path().to_owned(),
            scenes: 1,
            seed,
            size: (256, 256),
            ply: false,
            content,
            ..SynthConfig::default()
        };
        let m = tre::synth::generate(&cfg).unwrap();
        let mut seen = BTreeSet::new();
        for f in &m.scenes[0].frames {
            let labels = tre::io::read_labels(&dir.path().join(&f.dir).join("labels.png")).unwrap();
            seen.extend(labels.as_slice().iter().map(|&l| l as u8));
        }
        seen
    }

    #[test]
    fn every_indoor_and_urban_label_shows_in_the_frames() {
        for seed in [1, 2, 3, 4, 5, 6] {
            for (content, want) in [
                (Content::Indoor, &Category::INDOOR[..]),
                (Content::Urban, &Category::URBAN[..]),
            ] {
                let seen = labels_seen(content, seed);
                for c in want {
                    if *c == Category::Paving && !seen.contains(&c.label()) {
                        // A slab sidewalk (pavement) instead of block paving.
                        assert!(
                            seen.contains(&Category::Pavement.label()),
                            "{content} seed {seed}: no paving or pavement in {seen:?}"
                        );
                        continue;
                    }
                    assert!(
                        seen.contains(&c.label()),
                        "{content} seed {seed}: no {} ({}) in {seen:?}",
                        c.name(),
                        c.label()
                    );
                }
            }
        }
    }

    /// Robot camera (1 m up, 60° down, looking along +y) at 320×320.
    fn edge_scene(objects: Vec<Object>) -> (RenderedFrame, View, Annotation) {
        let terrain = Terrain {
            regions: vec![Region {
                centre: (0.0, 0.0),
                category: Category::Tile,
                seed: 2,
                steps: None,
            }],
            objects,
        };
        let view = robot_view(320);
        let f = render(&scene_of(terrain), &view, &clear_noon());
        let ann = annotate_frame(&f, &view);
        (f, view, ann)
    }

    /// Roughness of the boundary pixels whose points lie within 2 cm of the line y = `edge_y`
    /// and between heights `z0` and `z1` (world frame).
    fn edge_roughness(
        scene: &(RenderedFrame, View, Annotation),
        edge_y: f64,
        z: (f64, f64),
    ) -> Vec<f64> {
        let (f, view, ann) = scene;
        let rot = view.world_from_cam();
        let mut out = Vec::new();
        for v in 0..view.height {
            for u in 0..view.width {
                if !ann.boundary[(u, v)] {
                    continue;
                }
                let d = f.depth_m[(u, v)];
                let p = rot * view.intrinsics.back_project(u as f64, v as f64, d) + view.centre();
                if (p.y - edge_y).abs() < 0.02
                    && p.z > z.0 - 0.005
                    && p.z < z.1 + 0.005
                    && p.x.abs() < 0.4
                {
                    out.push(ann.roughness_m[(u, v)]);
                }
            }
        }
        out.sort_by(f64::total_cmp);
        out
    }

    fn floor(category: Category, y0: f64, y1: f64, base_m: f64) -> Object {
        let shape = Shape::rect((0.0, (y0 + y1) / 2.0), (10.0, (y1 - y0) / 2.0), 0.0);
        object(category, shape, Profile::Floor { base_m })
    }

    fn strip(category: Category, y0: f64, y1: f64, half_x: f64, top_m: f64) -> Object {
        let shape = Shape::rect((0.0, (y0 + y1) / 2.0), (half_x, (y1 - y0) / 2.0), 0.0);
        object(category, shape, Profile::Block { top_m })
    }

    fn report(what: &str, r: &[f64]) -> (f64, f64, f64) {
        assert!(r.len() >= 20, "{what}: {} edge pixels", r.len());
        let q = |t: f64| r[((r.len() - 1) as f64 * t) as usize];
        let (low, median, max) = (q(0.1), q(0.5), r[r.len() - 1]);
        eprintln!(
            "{what}: {} px, 10th percentile {:.1} cm, median {:.1} cm, max {:.1} cm",
            r.len(),
            100.0 * low,
            100.0 * median,
            100.0 * max
        );
        (low, median, max)
    }

    #[test]
    fn curb_sill_and_box_edges_show_in_the_ground_truth() {
        // Robot camera 1 m up, 60° down, looking along +y at straight edges across its view.
        let curb_drop = edge_scene(vec![
            floor(Category::Paving, -5.0, 1.2, 0.0),
            floor(Category::Asphalt, 1.2, 9.0, -0.12),
            strip(Category::Curb, 1.05, 1.2, 10.0, 0.0),
        ]);
        let curb_rise = edge_scene(vec![
            floor(Category::Asphalt, -5.0, 1.0, 0.0),
            floor(Category::Paving, 1.0, 9.0, 0.12),
            strip(Category::Curb, 1.0, 1.15, 10.0, 0.12),
        ]);
        let sill = edge_scene(vec![
            floor(Category::Tile, -5.0, 1.06, 0.0),
            floor(Category::Wood, 1.06, 9.0, 0.0),
            strip(Category::Sill, 1.0, 1.12, 10.0, 0.02),
        ]);
        let boxed = edge_scene(vec![strip(Category::Box, 0.7, 1.0, 0.3, 0.3)]);
        // A face (a step of the height field) belongs to the object on top of it.
        for (scene, category) in [(&boxed, Category::Box), (&curb_rise, Category::Curb)] {
            let (f, view, _) = scene;
            let rot = view.world_from_cam();
            let mut faces = 0;
            for (n, l) in f.normals_cam.as_slice().iter().zip(f.labels.as_slice()) {
                if n.x.is_finite() && (rot * n).z.abs() < 0.5 {
                    assert_eq!(
                        *l,
                        u32::from(category.label()),
                        "a face of the {category:?}"
                    );
                    faces += 1;
                }
            }
            assert!(faces > 500, "{category:?}: {faces} face pixels");
        }
        // Edges that hide what lies beyond (the far edge of a curb seen from the sidewalk, of a
        // sill, of a box top): the 3-D gap across them is at least the height, and the spec's
        // edge term gives at least the height on 90% of their boundary pixels.
        for (what, scene, edge_y, top, h) in [
            (
                "curb 12 cm seen from the sidewalk",
                &curb_drop,
                1.2,
                0.0,
                0.12,
            ),
            ("sill 2 cm, far edge", &sill, 1.12, 0.02, 0.02),
            ("box 30 cm, far edge", &boxed, 1.0, 0.3, 0.3),
        ] {
            let (low, _, _) = report(what, &edge_roughness(scene, edge_y, (0.0, top)));
            assert!(low >= h, "{what}: 10th percentile {low} m");
        }
        // Edges whose riser faces the camera (the curb seen from the road, the near side of a
        // sill or a box): the spec reads them as a ridge of the surface term (its 5 cm radius
        // takes in part of the riser), 1–3 cm whatever the height, as docs/synth.md says.
        for (what, scene, edge_y, top) in [
            ("curb 12 cm seen from the road", &curb_rise, 1.0, 0.12),
            ("sill 2 cm, near edge", &sill, 1.0, 0.02),
            ("box 30 cm, near edge", &boxed, 0.7, 0.3),
        ] {
            let (low, median, _) = report(what, &edge_roughness(scene, edge_y, (0.0, top)));
            assert!(
                low >= 0.005 && median >= 0.01,
                "{what}: {low} m, {median} m"
            );
        }
    }

    #[test]
    fn an_interrupted_run_resumes_keeping_complete_frames() {
        let (a, b) = (tempfile::tempdir().unwrap(), tempfile::tempdir().unwrap());
        let cfg = |out: &Path, resume: bool| SynthConfig {
            content: Content::Mixed,
            resume,
            ..small_config(out, 12)
        };
        tre::synth::generate(&cfg(a.path(), false)).unwrap();
        tre::synth::generate(&cfg(b.path(), false)).unwrap();
        // Interrupt b: no manifest or contact sheet yet, the run's settings recorded, one frame
        // half written, one not started, and a kept frame marked to show it is not rewritten.
        let root = b.path();
        std::fs::remove_file(root.join("dataset.json")).unwrap();
        std::fs::remove_file(root.join("contact_sheet.png")).unwrap();
        let settings = serde_json::to_string_pretty(&cfg(root, false)).unwrap();
        std::fs::write(root.join(tre::synth::dataset::RUN_FILE), settings).unwrap();
        std::fs::rename(
            root.join("scene_00001/view_1"),
            root.join("scene_00001/view_1.partial"),
        )
        .unwrap();
        std::fs::remove_file(root.join("scene_00001/view_1.partial/roughness.png")).unwrap();
        std::fs::remove_dir_all(root.join("scene_00000/view_2")).unwrap();
        let marked = root.join("scene_00000/view_1/rgb.png");
        std::fs::write(&marked, b"kept").unwrap();
        // Other settings are refused; the same ones resume.
        let other = SynthConfig {
            seed: 13,
            ..cfg(root, true)
        };
        let e = tre::synth::generate(&other).unwrap_err().to_string();
        assert!(e.contains("other settings"), "{e}");
        tre::synth::generate(&cfg(root, true)).unwrap();
        assert_eq!(std::fs::read(&marked).unwrap(), b"kept");
        std::fs::copy(a.path().join("scene_00000/view_1/rgb.png"), &marked).unwrap();
        let (fa, fb) = (files(a.path()), files(root));
        assert_eq!(
            fa.len(),
            fb.len(),
            "{:?}",
            fb.iter().map(|f| &f.0).collect::<Vec<_>>()
        );
        for ((na, ba), (nb, bb)) in fa.iter().zip(&fb) {
            assert_eq!(na, nb);
            assert!(ba == bb, "{na} differs after resuming");
        }
        // A finished dataset resumes to itself.
        tre::synth::generate(&cfg(root, true)).unwrap();
        assert_eq!(files(root).len(), fa.len());
    }

    /// Set `TRE_SYNTH_CONTENT_SHEET=docs/synth-content-sheet.png` to redraw the contact sheet of
    /// docs/synth.md: two indoor and two urban frames (RGB, labels, spec roughness 0–5 cm).
    #[test]
    fn content_contact_sheet() {
        use tre::io::sheet::{
            categorical_legend, colour_bar_legend, contact_sheet, fit_within, roughness_panel,
            stack, Panel,
        };
        use tre::synth::dataset::{build_scene, scene_views, view_conditions};
        let Ok(out) = std::env::var("TRE_SYNTH_CONTENT_SHEET") else {
            return;
        };
        let mut panels = Vec::new();
        for (content, seed, view) in [
            (Content::Indoor, 1, 2),
            (Content::Indoor, 4, 6),
            (Content::Urban, 1, 5),
            (Content::Urban, 2, 3),
        ] {
            let cfg = SynthConfig {
                size: (384, 288),
                seed,
                content,
                ..SynthConfig::default()
            };
            let views = scene_views(&cfg, 0);
            let scene = build_scene(&cfg, 0, &views);
            let f = render(&scene, &views[view], &view_conditions(&cfg, 0, view as u32));
            let ann = annotate_frame(&f, &views[view]);
            let fit = |img: image::RgbImage| fit_within(&img, 288, 216);
            let title = format!("{content} seed {seed} view {view}");
            panels.push(Panel::new(title, fit(f.rgb.clone())));
            panels.push(Panel::new(
                "labels",
                fit(tre::io::colormap::labels(&f.labels)),
            ));
            panels.push(Panel::new(
                "spec roughness",
                fit(roughness_panel(&ann.roughness_m, 0.05)),
            ));
        }
        let palette = tre::io::colormap::labels(&Grid::from_fn(21, 1, |u, _| u as u32));
        let entries: Vec<(&str, image::Rgb<u8>)> = (Category::INDOOR.iter())
            .chain(&Category::URBAN)
            .chain([&Category::Pavement])
            .map(|c| (c.name(), *palette.get_pixel(u32::from(c.label()), 0)))
            .collect();
        let legend = stack(&[
            colour_bar_legend(480, 0.05, &[0.0, 1.0, 2.0, 3.0, 4.0, 5.0]),
            categorical_legend(&entries[..8]),
            categorical_legend(&entries[8..]),
        ]);
        let sheet = contact_sheet(&panels, 3, Some(&legend));
        tre::io::save(Path::new(&out), &image::DynamicImage::ImageRgb8(sheet)).unwrap();
    }
}
