//! Geometry core: camera round trips, LS normals, gravity frame and the DSAC sampler.
#![allow(clippy::unwrap_used)] // Test helpers fail loudly by design.

use approx::assert_relative_eq;
use nalgebra::{Rotation3, Vector3};
use proptest::prelude::*;
use tre_core::geometry::dsac::{self, DsacConfig, CANDIDATES};
use tre_core::geometry::raycast::{render_depth, MarchConfig};
use tre_core::geometry::{
    normals::{ls_normals, Neighbourhood},
    Grid, Intrinsics, Mounting, Vec3,
};

fn camera(w: usize, h: usize) -> Intrinsics {
    Intrinsics::from_hfov(w, h, 70.0).unwrap()
}

/// Depth of the plane `n·p = d` (camera frame) seen by `k`; 0 where it is behind the camera.
fn plane_depth(k: &Intrinsics, (w, h): (usize, usize), n: &Vec3, d: f64) -> Grid<f64> {
    Grid::from_fn(w, h, |u, v| {
        let ray = k.back_project(u as f64, v as f64, 1.0);
        let z = d / n.dot(&ray);
        if z > 0.0 && z < 5.0 {
            z
        } else {
            0.0
        }
    })
}

fn angle_deg(a: &Vec3, b: &Vec3) -> f64 {
    (a.dot(b) / (a.norm() * b.norm()))
        .clamp(-1.0, 1.0)
        .acos()
        .to_degrees()
}

proptest! {
    #[test]
    fn project_back_project_is_identity(
        fx in 50.0..2000.0f64, fy in 50.0..2000.0f64, cx in -100.0..800.0f64, cy in -100.0..800.0f64,
        u in -500.0..1500.0f64, v in -500.0..1500.0f64, z in 0.01..100.0f64,
    ) {
        let k = Intrinsics::new(fx, fy, cx, cy).unwrap();
        let p = k.back_project(u, v, z);
        let (u2, v2) = k.project(&p).unwrap();
        prop_assert!((u2 - u).abs() < 1e-9 * (1.0 + u.abs()));
        prop_assert!((v2 - v).abs() < 1e-9 * (1.0 + v.abs()));
        prop_assert!((p.z - z).abs() < 1e-12 * z);
    }

    #[test]
    fn plane_fit_is_rotation_invariant(rx in -3.0..3.0f64, ry in -3.0..3.0f64, rz in -3.0..3.0f64) {
        let rot = Rotation3::from_euler_angles(rx, ry, rz);
        let mut m = tre_core::geometry::Moments::default();
        let pts: Vec<Vec3> = (0..20).map(|i| {
            let (a, b) = ((i % 5) as f64 * 0.01, (i / 5) as f64 * 0.013);
            rot * Vector3::new(a, b, 0.001 * ((i * 7) % 3) as f64)
        }).collect();
        for p in &pts { m.add(p); }
        let mut m0 = tre_core::geometry::Moments::default();
        for p in &pts { m0.add(&(rot.inverse() * p)); }
        let n = m.fit(&Vec3::zeros()).unwrap().normal;
        let n0 = m0.fit(&Vec3::zeros()).unwrap().normal;
        prop_assert!((n.dot(&(rot * n0)).abs() - 1.0).abs() < 1e-9);
    }
}

#[test]
fn invalid_pixels_stay_invalid() {
    let k = camera(4, 3);
    let depth = Grid::from_vec(
        4,
        3,
        vec![
            1.0,
            0.0,
            f64::NAN,
            -1.0,
            2.0,
            2.0,
            f64::INFINITY,
            1.0,
            1.0,
            1.0,
            1.0,
            0.0,
        ],
    )
    .unwrap();
    let pts = k.back_project_map(&depth);
    let valid: Vec<bool> = pts
        .as_slice()
        .iter()
        .map(tre_core::geometry::is_valid_point)
        .collect();
    assert_eq!(
        valid,
        [true, false, false, false, true, true, false, true, true, true, true, false]
    );
}

#[test]
fn ls_normals_of_tilted_planes_within_a_tenth_of_a_degree() {
    let (w, h) = (320, 240);
    let k = camera(w, h);
    for (i, n) in [
        Vector3::new(0.0, -1.0, -1.0),
        Vector3::new(0.3, -0.8, -0.2),
        Vector3::new(-0.5, 0.2, -1.0),
    ]
    .iter()
    .enumerate()
    {
        let n = n.normalize();
        let depth = plane_depth(&k, (w, h), &n, -1.2 - i as f64 * 0.3);
        let pts = k.back_project_map(&depth);
        let normals = ls_normals(&pts, k.fx_px, &Neighbourhood::default());
        let (mut checked, mut valid) = (0, 0);
        for (p, m) in pts.as_slice().iter().zip(normals.as_slice()) {
            valid += usize::from(tre_core::geometry::is_valid_point(p));
            // Pixels whose neighbourhood holds fewer than 3 points have no normal.
            if tre_core::geometry::is_valid_point(m) || m.x.is_finite() {
                // Oriented towards the camera: n·p < 0.
                assert!(m.dot(p) < 0.0);
                assert!(angle_deg(m, &n) < 0.1, "plane {i}: {m:?} vs {n:?}");
                checked += 1;
            }
        }
        assert!(
            checked > 1000 && checked * 10 > valid * 9,
            "{checked} of {valid}"
        );
    }
}

#[test]
fn ls_normals_of_a_sphere_within_a_tenth_of_a_degree() {
    // Sphere of radius 1 m centred 3 m in front of a VGA camera, default neighbourhood (R = 5 cm).
    // On a curved surface the LS normal is the normal at the neighbourhood's centroid; the
    // discrete in/out-of-radius decisions make that centroid drift by about R/n, which grows
    // with obliquity, so the check covers the part of the sphere facing the camera within 45°.
    let (w, h) = (640, 480);
    let k = camera(w, h);
    let (centre, radius) = (Vector3::new(0.0, 0.0, 3.0), 1.0);
    let depth = Grid::from_fn(w, h, |u, v| {
        let d = k.back_project(u as f64, v as f64, 1.0).normalize();
        let b = d.dot(&centre);
        let disc = b * b - centre.norm_squared() + radius * radius;
        if disc > 0.0 {
            (b - disc.sqrt()) * d.z
        } else {
            0.0
        }
    });
    let pts = k.back_project_map(&depth);
    let normals = ls_normals(&pts, k.fx_px, &Neighbourhood::default());
    let mut checked = 0;
    for (p, m) in pts.as_slice().iter().zip(normals.as_slice()) {
        let truth = (p - centre).normalize();
        // Away from the silhouette, where the neighbourhood is a full cap.
        if tre_core::geometry::is_valid_point(p)
            && truth.dot(&(-p.normalize())) > std::f64::consts::FRAC_1_SQRT_2
        {
            assert!(angle_deg(m, &truth) < 0.1, "{m:?} vs {truth:?}");
            checked += 1;
        }
    }
    assert!(checked > 500, "{checked}");
}

#[test]
fn gravity_frame_puts_rendered_ground_at_zero() {
    let (w, h) = (64, 48);
    let k = camera(w, h);
    let m = Mounting::new(50f64.to_radians(), 0.8).unwrap();
    let depth = render_depth(
        &|_x: f64, _y: f64| 0.0,
        &k,
        &m,
        (w, h),
        &MarchConfig::default(),
    );
    let pts = k.back_project_map(&depth);
    let mut n = 0;
    for p in pts
        .as_slice()
        .iter()
        .filter(|p| tre_core::geometry::is_valid_point(p))
    {
        assert!(m.gravity_from_cam_point(p).z.abs() < 1e-9);
        n += 1;
    }
    assert!(n > w * h / 2);
    // The camera's optical axis is pitched 50° down: the ground normal has slope 0.
    let up_cam = m.gravity_from_cam().transpose() * Vector3::z();
    assert_relative_eq!(m.slope_rad(&up_cam), 0.0, epsilon = 1e-12);
}

/// A small tilted-plane point map with a few off-plane outliers.
fn plane_with_outliers(w: usize, h: usize) -> (tre_core::geometry::PointMap, Vec3) {
    let k = camera(w, h);
    let n = Vector3::new(0.2, -0.9, -0.4).normalize();
    let depth = plane_depth(&k, (w, h), &n, -1.0);
    let mut pts = k.back_project_map(&depth);
    for (i, p) in pts.as_mut_slice().iter_mut().enumerate() {
        if i % 5 == 0 {
            *p *= 1.05;
        }
    }
    (pts, n)
}

/// Logits that put all probability on the coplanar (non-outlier) candidates.
fn coplanar_logits(w: usize, h: usize) -> Vec<f32> {
    let mut logits = vec![-1e4f32; CANDIDATES * w * h];
    for y in 0..h {
        for x in 0..w {
            for k in 0..CANDIDATES {
                let (dx, dy) = dsac::candidate_offset(k);
                let (cx, cy) = (x as isize + dx, y as isize + dy);
                let inside = cx >= 0 && cy >= 0 && (cx as usize) < w && (cy as usize) < h;
                if inside && !(cy as usize * w + cx as usize).is_multiple_of(5) {
                    logits[k * w * h + y * w + x] = 0.0;
                }
            }
        }
    }
    logits
}

#[test]
fn dsac_with_probability_on_coplanar_neighbours_returns_that_plane() {
    let (w, h) = (40, 30);
    let (pts, n) = plane_with_outliers(w, h);
    let logits = coplanar_logits(w, h);
    let normals = dsac::dsac_normals(
        &pts,
        &logits,
        &DsacConfig {
            seed: 9,
            ..Default::default()
        },
    )
    .unwrap();
    for (i, (p, m)) in pts.as_slice().iter().zip(normals.as_slice()).enumerate() {
        if i % 5 != 0 && tre_core::geometry::is_valid_point(p) {
            assert!(angle_deg(m, &n) < 1e-4, "pixel {i}: {m:?}");
            assert!(m.dot(p) < 0.0);
        }
    }
}

#[test]
fn dsac_is_identical_on_one_and_two_threads() {
    let (w, h) = (48, 36);
    let (pts, _) = plane_with_outliers(w, h);
    // Varied logits so that the draws matter.
    let logits: Vec<f32> = (0..CANDIDATES * w * h)
        .map(|i| ((i * 2654435761usize) % 1000) as f32 / 250.0)
        .collect();
    let cfg = DsacConfig {
        seed: 42,
        ..Default::default()
    };
    let run = |threads| {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap();
        pool.install(|| dsac::dsac_normals(&pts, &logits, &cfg).unwrap())
    };
    let (a, b) = (run(1), run(2));
    let bits = |g: &Grid<Vec3>| {
        g.as_slice()
            .iter()
            .flat_map(|v| v.iter().map(|c| c.to_bits()).collect::<Vec<_>>())
            .collect::<Vec<_>>()
    };
    assert_eq!(bits(&a), bits(&b));
    // A different seed draws differently somewhere.
    let c = dsac::dsac_normals(&pts, &logits, &DsacConfig { seed: 43, ..cfg }).unwrap();
    assert_ne!(bits(&a), bits(&c));
}

#[test]
fn sampler_draws_distinct_candidates_with_probability() {
    let mut rho = [0.0; CANDIDATES];
    for k in [3usize, 10, 24, 40] {
        rho[k] = 0.25;
    }
    for hyp in 0..200 {
        let t = dsac::sample_triple(&rho, 1, 77, hyp).unwrap();
        assert!(t[0] != t[1] && t[1] != t[2] && t[0] != t[2]);
        assert!(t.iter().all(|&k| rho[k] > 0.0));
    }
    rho[3] = 0.0;
    rho[10] = 0.0;
    assert!(dsac::sample_triple(&rho, 1, 77, 0).is_none());
}

#[test]
fn bad_intrinsics_are_refused() {
    assert!(Intrinsics::new(0.0, 500.0, 1.0, 1.0)
        .unwrap_err()
        .to_string()
        .contains("fx"));
    assert!(Intrinsics::new(500.0, -3.0, 1.0, 1.0)
        .unwrap_err()
        .to_string()
        .contains("fy"));
    assert!(Intrinsics::new(500.0, 500.0, f64::NAN, 1.0).is_err());
    assert!(Mounting::new(2.0, 1.0).is_err());
    assert!(Mounting::new(0.5, -1.0).is_err());
}
