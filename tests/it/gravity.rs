//! Gravity from depth (`tre_core::geometry::floor`) against the gravity that real sequences
//! state: the 7-Scenes kitchen (a pose and the gravity direction for every frame) and KITTI
//! (cameras 1.65 m up, pitch about 0).
#![allow(clippy::unwrap_used)] // Test helpers fail loudly by design.

use std::path::{Path, PathBuf};

use tre::geometry::floor::{fit_floor, FloorFit, FloorFitConfig};
use tre::geometry::Vec3;

use crate::common::shared_data;

/// A sequence folder of `../shared/data/real-rgbd-2`, where that is there (else the test returns
/// early: [`shared_data`]).
fn real2(seq: &str) -> Option<PathBuf> {
    shared_data(&format!("data/real-rgbd-2/{seq}"))
}

/// The fit on one depth PNG of a sequence (its camera file's scale and intrinsics).
fn fit(seq: &Path, depth: &str) -> Result<FloorFit, tre::geometry::floor::NoFloor> {
    let (cam, k) = tre::io::read_camera(&seq.join("intrinsics.json")).unwrap();
    let d = tre::io::read_depth(&seq.join(depth), cam.depth_scale.unwrap()).unwrap();
    fit_floor(&k.back_project_map(&d), &FloorFitConfig::default())
}

/// Angle between two directions, degrees.
fn angle_deg(a: &Vec3, b: &Vec3) -> f64 {
    (a.dot(b) / (a.norm() * b.norm()))
        .clamp(-1.0, 1.0)
        .acos()
        .to_degrees()
}

/// Up in the camera frame from a camera-to-world pose file and the world's gravity (down).
fn stated_up(pose: &Path, gravity_down: &Vec3) -> Vec3 {
    let text = std::fs::read_to_string(pose).unwrap();
    let v: Vec<f64> = text
        .split_whitespace()
        .map(|t| t.parse().unwrap())
        .collect();
    let r = nalgebra::Matrix3::new(v[0], v[1], v[2], v[4], v[5], v[6], v[8], v[9], v[10]);
    -(r.transpose() * gravity_down)
}

#[test]
fn kitchen_gravity_from_depth_is_within_two_degrees_of_the_stated_one() {
    let Some(seq) = real2("sevenscenes_redkitchen") else {
        return;
    };
    let g: serde_json::Value =
        serde_json::from_slice(&std::fs::read(seq.join("gravity.json")).unwrap()).unwrap();
    let g: Vec<f64> = serde_json::from_value(g["gravity"].clone()).unwrap();
    let down = Vec3::new(g[0], g[1], g[2]);
    let (mut confident, mut within, mut errors) = (0, 0, Vec::new());
    let mut frames = 0;
    // The test part of the sequence (frames 800–995, docs/real-splits.md), reported apart.
    let (mut test_fitted, mut test_errors) = (0, Vec::<f64>::new());
    for i in (0..1000).step_by(5) {
        let name = format!("frame-{i:06}");
        let Ok(f) = fit(&seq, &format!("depth/{name}.png")) else {
            continue;
        };
        frames += 1;
        test_fitted += usize::from(i >= 800);
        if !f.confident {
            continue;
        }
        confident += 1;
        let e = angle_deg(
            &f.up_in_cam,
            &stated_up(&seq.join(format!("poses/{name}.txt")), &down),
        );
        errors.push(e);
        if i >= 800 {
            test_errors.push(e);
        }
        within += usize::from(e <= 2.0);
    }
    println!(
        "kitchen test part: {test_fitted} of 40 frames fitted, {} confident, errors {:?}",
        test_errors.len(),
        test_errors
            .iter()
            .map(|e| format!("{e:.2}"))
            .collect::<Vec<_>>()
    );
    errors.sort_by(f64::total_cmp);
    let median = errors[errors.len() / 2];
    let p90 = errors[errors.len() * 9 / 10];
    println!(
        "kitchen: {frames} frames fitted, {confident} confident; of those {within} within 2° \
         (median {median:.2}°, p90 {p90:.2}°, max {:.2}°)",
        errors.last().unwrap()
    );
    // The thresholds (support ≥ 5%, ≤ 1% below) were chosen on frames 0–795 (the training and
    // validation parts, docs/real-splits.md); measured over all 200 frames: 53 confident,
    // 43 within 2°, median 1.36°, p90 2.54°, max 5.57° (docs/gravity.md).
    assert!(confident * 5 >= frames, "{confident} of {frames} confident");
    assert!(
        within * 100 >= confident * 80,
        "{within} of {confident} within 2°"
    );
    assert!(median <= 1.5, "median {median:.2}°");
    assert!(p90 <= 3.0, "p90 {p90:.2}°");
}

#[test]
fn kitti_gravity_from_lidar_depth_matches_the_stated_mounting() {
    let Some(seq) = real2("kitti_0023") else {
        return;
    };
    for i in 0..7 {
        let f = fit(&seq, &format!("depth/{i:010}.png")).unwrap();
        println!(
            "kitti {i}: pitch {:.2}°, roll {:.2}°, height {:.3} m, support {:.2}",
            f.pitch_rad.to_degrees(),
            f.roll_rad.to_degrees(),
            f.height_m,
            f.support
        );
        assert!(f.confident, "{f:?}");
        // Stated: pitch about 0, 1.65 m above the road.
        assert!(f.pitch_rad.to_degrees().abs() <= 2.0, "{f:?}");
        assert!(f.roll_rad.to_degrees().abs() <= 2.0, "{f:?}");
        assert!((f.height_m - 1.65).abs() <= 0.15, "{f:?}");
    }
}
