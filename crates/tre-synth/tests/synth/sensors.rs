//! Depth-sensor models on analytic planes and steps, and against real Kinect floor.

use super::*;
use image::RgbImage;
use tre_core::geometry::hash::uniform;
use tre_synth::sensor::{simulate, SensorInput, SensorModel};

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
    tre_synth::dataset::generate(&cfg(a.path(), SensorPreset::Exact)).unwrap();
    tre_synth::dataset::generate(&cfg(b.path(), SensorPreset::KinectV1)).unwrap();
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
