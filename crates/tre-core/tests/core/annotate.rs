//! Roughness annotator (spec v1) on synthetic scenes with known answers and on bad input (on
//! the real RGB-D frames: `tests/it/annotate_real.rs` of the `tre` package).
#![allow(clippy::unwrap_used)] // Test helpers fail loudly by design.

use nalgebra::Vector3;
use tre_core::geometry::raycast::{render_depth, MarchConfig};
use tre_core::geometry::{normals::Neighbourhood, Grid, Intrinsics, Mounting, Vec3};
use tre_core::roughness::{
    annotate::{annotate, AnnotateConfig, AnnotateInput},
    RoughnessError,
};

/// The spec (annotation spec v1, default settings) on a depth map alone.
fn spec(depth: &Grid<f64>, k: &Intrinsics) -> tre_core::roughness::annotate::Annotation {
    annotate(&AnnotateInput::depth(depth, k), &AnnotateConfig::default()).unwrap()
}

/// The paper's robot camera: 1 m high, looking down 60°, 256×256 with a 60° field of view.
fn robot_camera() -> (Intrinsics, Mounting, (usize, usize)) {
    (
        Intrinsics::from_hfov(256, 256, 60.0).unwrap(),
        Mounting::default(),
        (256, 256),
    )
}

/// Every valid pixel of `ann` reads flat (under a micrometre).
fn assert_flat(ann: &tre_core::roughness::annotate::Annotation) {
    assert!(ann
        .roughness_m
        .as_slice()
        .iter()
        .filter(|r| r.is_finite())
        .all(|r| *r < 1e-6));
}

/// Gravity-frame points of a depth map.
fn gravity_points(depth: &Grid<f64>, k: &Intrinsics, m: &Mounting) -> Grid<Vec3> {
    k.back_project_map(depth)
        .map(|p| m.gravity_from_cam_point(p))
}

#[test]
fn flat_planes_in_any_pose_read_zero() {
    let (w, h) = (160, 120);
    let k = Intrinsics::from_hfov(w, h, 70.0).unwrap();
    let poses = [
        Vector3::new(0.0, -1.0, -1.0),
        Vector3::new(0.3, -0.7, -0.4),
        Vector3::new(-0.2, 0.1, -1.0),
        Vector3::new(0.9, 0.1, -0.3),
    ];
    for n in poses.iter().map(|n| n.normalize()) {
        let depth = Grid::from_fn(w, h, |u, v| {
            let z = -1.5 / n.dot(&k.back_project(u as f64, v as f64, 1.0));
            if z > 0.0 && z < 6.0 {
                z
            } else {
                0.0
            }
        });
        let ann = spec(&depth, &k);
        let mut n_valid = 0;
        for r in ann.roughness_m.as_slice().iter().filter(|r| r.is_finite()) {
            assert!(*r < 1e-6, "plane {n:?}: roughness {r}");
            n_valid += 1;
        }
        assert!(n_valid > w * h / 4, "{n_valid}");
        // With the true normals given, too.
        let normals = Grid::new(w, h, n);
        let input = AnnotateInput {
            depth_m: &depth,
            intrinsics: &k,
            normals: Some(&normals),
            labels: None,
        };
        let ann = annotate(&input, &AnnotateConfig::default()).unwrap();
        assert_flat(&ann);
    }
}

/// Renders ground at height 0 before `edge_y` (metres ahead) and `step_m` beyond it.
fn step_scene(step_m: f64, edge_y: f64) -> (Grid<f64>, Intrinsics, Mounting) {
    let (k, m, size) = robot_camera();
    let field = move |_x: f64, y: f64| if y < edge_y { 0.0 } else { step_m };
    (
        render_depth(&field, &k, &m, size, &MarchConfig::default()),
        k,
        m,
    )
}

#[test]
fn step_up_gives_a_ridge_along_its_edge_and_zero_beyond_the_radius() {
    let edge_y = 0.6;
    let (depth, k, m) = step_scene(0.10, edge_y);
    let ann = spec(&depth, &k);
    let g = gravity_points(&depth, &k, &m);
    let (mut ridge_max, mut far_max, mut far_n) = (0.0f64, 0.0f64, 0);
    for (p, r) in g.as_slice().iter().zip(ann.roughness_m.as_slice()) {
        if !r.is_finite() {
            continue;
        }
        // Distance to the two edges of the step: the foot (y = edge, z = 0) and the lip (z = 0.1).
        let d_foot = ((p.y - edge_y).powi(2) + p.z.powi(2)).sqrt();
        let d_lip = ((p.y - edge_y).powi(2) + (p.z - 0.10).powi(2)).sqrt();
        if d_foot.min(d_lip) < 0.02 {
            ridge_max = ridge_max.max(*r);
        }
        if d_foot.min(d_lip) > 0.05 + 0.01 {
            far_max = far_max.max(*r);
            far_n += 1;
        }
    }
    assert!((0.015..0.04).contains(&ridge_max), "ridge {ridge_max}");
    assert!(
        far_n > 10_000 && far_max < 1e-6,
        "beyond R: max {far_max} over {far_n} px"
    );
}

#[test]
fn drop_gives_at_least_ten_cm_on_the_boundary_decaying_over_the_band() {
    // Ground 10 cm up near the robot, then a drop: the lower ground is partly hidden.
    let edge_y = 0.6;
    let (k, m, size) = robot_camera();
    let field = move |_x: f64, y: f64| if y < edge_y { 0.10 } else { 0.0 };
    let depth = render_depth(&field, &k, &m, size, &MarchConfig::default());
    let ann = spec(&depth, &k);
    let (w, h) = size;
    let mut checked = 0;
    for x in 10..w - 10 {
        let column: Vec<usize> = (0..h).filter(|&y| ann.boundary[(x, y)]).collect();
        assert!(!column.is_empty(), "column {x} has no boundary");
        for &y in &column {
            assert!(
                ann.roughness_m[(x, y)] >= 0.1,
                "({x}, {y}): {}",
                ann.roughness_m[(x, y)]
            );
        }
        // Below the lowest boundary pixel (nearer the robot), the band decays.
        let yb = *column.iter().max().unwrap();
        let r: Vec<f64> = (0..5).map(|d| ann.roughness_m[(x, yb + d)]).collect();
        assert!(
            r.windows(2).all(|p| p[1] <= p[0]),
            "({x}): not decaying {r:?}"
        );
        // e·exp(−d²/2σ²): 41% of the peak 2 px away, 3% at 4 px (σ = 1.5 px).
        assert!(r[2] > 0.3 * r[0] && r[4] < 0.05 * r[0], "({x}): band {r:?}");
        checked += 1;
    }
    assert!(checked > 200);
}

/// Bessel J_n(x) by its power series (enough terms for x < 20).
fn bessel_j(n: i32, x: f64) -> f64 {
    let mut term = (x / 2.0).powi(n) / (1..=n).map(f64::from).product::<f64>();
    let mut sum = term;
    for k in 1..60 {
        term *= -(x * x / 4.0) / (f64::from(k) * f64::from(k + n));
        sum += term;
    }
    sum
}

#[test]
fn sinusoidal_bumps_give_the_analytic_roughness() {
    // Egg-crate bumps h = A cos(kx) cos(ky) seen from 1 m straight down. For R ≪ curvature
    // radius… is not needed: over the disk of radius R the mean of h is h(x0)·2J1(√2kR)/(√2kR),
    // so the distance to the local plane is |h(x0)|·(1 − 2J1(√2kR)/(√2kR)) up to the LS
    // plane's small tilt (cos of a slope ≤ 0.1 rad here).
    let (amp, wavelength, radius) = (0.005, 0.10, 0.05);
    let kw = 2.0 * std::f64::consts::PI / wavelength;
    let (w, h) = (200, 200);
    let k = Intrinsics::new(500.0, 500.0, 99.5, 99.5).unwrap();
    let m = Mounting::new(90f64.to_radians(), 1.0).unwrap();
    let field = move |x: f64, y: f64| amp * (kw * x).cos() * (kw * y).cos();
    let depth = render_depth(
        &field,
        &k,
        &m,
        (w, h),
        &MarchConfig {
            max_step_m: 0.005,
            ..Default::default()
        },
    );
    // A window that holds the whole R-ball (R·fx/z = 25 px), so the neighbourhood is the disk.
    let cfg = AnnotateConfig {
        hood: Neighbourhood {
            radius_m: radius,
            max_half_width: 26,
        },
        ..Default::default()
    };
    let ann = annotate(&AnnotateInput::depth(&depth, &k), &cfg).unwrap();
    let x = std::f64::consts::SQRT_2 * kw * radius;
    let factor = 1.0 - 2.0 * bessel_j(1, x) / x;
    let g = gravity_points(&depth, &k, &m);
    let tolerance = 0.35e-3; // 7% of the amplitude
    let (mut worst, mut crest_max) = (0.0f64, 0.0f64);
    for y in 30..h - 30 {
        for x in 30..w - 30 {
            let p = g[(x, y)];
            let expected = (amp * (kw * p.x).cos() * (kw * p.y).cos()).abs() * factor;
            let r = ann.roughness_m[(x, y)];
            worst = worst.max((r - expected).abs());
            crest_max = crest_max.max(r);
        }
    }
    assert!(worst < tolerance, "worst |r − analytic| = {worst} m");
    assert!(
        (crest_max - amp * factor).abs() < tolerance,
        "crest {crest_max} vs {}",
        amp * factor
    );
    assert!(
        ann.boundary.as_slice().iter().all(|b| !b),
        "smooth bumps must not split into segments"
    );
}

#[test]
fn all_invalid_depth_is_a_clear_error() {
    let k = Intrinsics::new(500.0, 500.0, 10.0, 10.0).unwrap();
    let depth = Grid::new(20, 20, 0.0);
    let err = annotate(
        &AnnotateInput::depth(&depth, &k),
        &AnnotateConfig::default(),
    )
    .unwrap_err();
    assert_eq!(
        err,
        RoughnessError::NoValidDepth {
            width: 20,
            height: 20
        }
    );
    assert!(err.to_string().contains("no valid pixel"));
}

#[test]
fn normals_missing_where_there_is_depth_are_an_error_unless_those_pixels_are_void() {
    let k = Intrinsics::new(500.0, 500.0, 10.0, 10.0).unwrap();
    let depth = Grid::new(20, 20, 1.0);
    let mut normals = Grid::new(20, 20, Vec3::new(0.0, 0.0, -1.0));
    normals[(3, 2)] = Vec3::new(f64::NAN, 0.0, 0.0);
    normals[(5, 7)] = Vec3::zeros();
    let run = |labels: Option<&Grid<u32>>| {
        annotate(
            &AnnotateInput {
                depth_m: &depth,
                intrinsics: &k,
                normals: Some(&normals),
                labels,
            },
            &AnnotateConfig::default(),
        )
    };
    let err = run(None).unwrap_err();
    assert_eq!(
        err,
        RoughnessError::MissingNormals {
            missing: 2,
            valid: 400,
            first: (3, 2)
        }
    );
    assert!(err.to_string().contains("2 of the 400 pixels"), "{err}");
    // Marked void, those pixels have no data, and the rest is annotated with the normals given.
    let mut labels = Grid::new(20, 20, 1u32);
    labels[(3, 2)] = 0;
    labels[(5, 7)] = 0;
    let ann = run(Some(&labels)).unwrap();
    assert!(ann.roughness_m[(3, 2)].is_nan() && ann.roughness_m[(5, 7)].is_nan());
    assert!(ann.roughness_m[(10, 10)] < 1e-9);
}

#[test]
fn labels_of_another_size_are_a_clear_error() {
    let k = Intrinsics::new(500.0, 500.0, 10.0, 10.0).unwrap();
    let depth = Grid::new(20, 20, 1.0);
    let labels = Grid::new(21, 20, 1u32);
    let input = AnnotateInput {
        labels: Some(&labels),
        ..AnnotateInput::depth(&depth, &k)
    };
    let err = annotate(&input, &AnnotateConfig::default()).unwrap_err();
    assert!(
        err.to_string()
            .contains("labels is 21×20 but the depth map is 20×20"),
        "{err}"
    );
}

#[test]
fn labels_split_segments_and_void_is_no_data() {
    // A flat plane with two labels: the label border becomes a boundary, void pixels have none.
    let (w, h) = (40, 30);
    // Neighbours 3.5 mm apart (diagonals under 0.5ε), so the label border adds no edge term.
    let k = Intrinsics::from_hfov(w, h, 4.0).unwrap();
    let depth = Grid::new(w, h, 2.0);
    let labels = Grid::from_fn(w, h, |x, y| {
        if y == 0 {
            0
        } else if x < 20 {
            1
        } else {
            2
        }
    });
    let input = AnnotateInput {
        labels: Some(&labels),
        ..AnnotateInput::depth(&depth, &k)
    };
    let ann = annotate(&input, &AnnotateConfig::default()).unwrap();
    assert!(ann.roughness_m.row(0).iter().all(|r| r.is_nan()));
    assert!(ann.boundary[(19, 10)] && ann.boundary[(20, 10)] && !ann.boundary[(10, 10)]);
    assert_eq!(ann.segments.as_slice().iter().max(), Some(&2));
    // Neighbours on a flat plane are close: no edge term, roughness stays ~0.
    assert_flat(&ann);
}
