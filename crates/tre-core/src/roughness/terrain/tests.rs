use super::steps::may_spread;
use super::*;
use crate::geometry::eigen_plane;
use crate::geometry::hash::uniform;
use crate::geometry::{Grid, Intrinsics};
use crate::roughness::annotate::{annotate, AnnotateConfig, AnnotateInput};
use crate::roughness::noise::SensorPreset;

/// Ground seen by a camera `height_m` up, pitched `pitch_deg` down: the depth of each pixel's
/// ray where it meets the ground, the ground `drop_m` lower in rows above `drop_row` (a drop
/// edge across the image), `keep` choosing the pixels with a return, `noise_m(z, x, y)` added.
fn ground(
    k: &Intrinsics,
    (w, h): (usize, usize),
    (height_m, pitch_deg): (f64, f64),
    (drop_row, drop_m): (usize, f64),
    keep: impl Fn(usize, usize) -> bool,
    noise_m: impl Fn(f64, usize, usize) -> f64,
) -> Grid<f64> {
    let b = pitch_deg.to_radians();
    let down = Vec3::new(0.0, b.cos(), b.sin());
    Grid::from_fn(w, h, |x, y| {
        let ray = Vec3::new(
            (x as f64 - k.cx_px) / k.fx_px,
            (y as f64 - k.cy_px) / k.fy_px,
            1.0,
        );
        let level = if y < drop_row {
            height_m + drop_m
        } else {
            height_m
        };
        let t = level / ray.dot(&down);
        if t > 0.0 && keep(x, y) {
            t + noise_m(t, x, y)
        } else {
            0.0
        }
    })
}

/// The terrain estimate of `depth` with the default settings.
fn estimate(k: &Intrinsics, depth: &Grid<f64>, noise: Option<&SensorNoise>) -> TerrainMaps {
    terrain(
        &k.back_project_map(depth),
        k,
        noise,
        &TerrainConfig::default(),
    )
}

/// A normal deviate from the counter-based hash (Box–Muller).
fn gauss(x: usize, y: usize) -> f64 {
    let i = (y * 10_000 + x) as u64;
    let (u1, u2) = (uniform(7, i, 0, 0).max(1e-12), uniform(7, i, 0, 1));
    (-2.0 * u1.ln()).sqrt() * (std::f64::consts::TAU * u2).cos()
}

fn share_at_least(r: &Grid<f64>, rows: std::ops::Range<usize>, t: f64) -> (f64, usize) {
    let (mut n, mut hit) = (0usize, 0usize);
    for y in rows {
        for &v in r.row(y) {
            if v.is_finite() {
                n += 1;
                hit += usize::from(v >= t);
            }
        }
    }
    (hit as f64 / n.max(1) as f64, n)
}

#[test]
fn scan_line_gaps_are_no_steps_but_a_drop_is() {
    // KITTI-like: 1242 x 375 cropped, camera 1.65 m up, level; a return on every 5th row.
    let k = Intrinsics::new(721.5, 721.5, 300.0, 40.0).unwrap();
    let lidar = SensorNoise::Preset(SensorPreset::Lidar);
    let noise = |z: f64, x: usize, y: usize| lidar.sigma_z_m(z) * gauss(x, y);
    let flat = ground(
        &k,
        (600, 120),
        (1.65, 0.0),
        (0, 0.0),
        |_, y| y % 5 == 0,
        noise,
    );
    let t = estimate(&k, &flat, Some(&lidar));
    let (share, n) = share_at_least(&t.roughness_m, 60..120, 0.05);
    assert!(n > 1000, "{n} estimates");
    assert!(
        share < 0.01,
        "flat ground with scan-line gaps: {share} read >= 5 cm"
    );
    // The spec reads the gaps as edges.
    let spec = annotate(&AnnotateInput::depth(&flat, &k), &AnnotateConfig::default()).unwrap();
    let (spec_share, _) = share_at_least(&spec.roughness_m, 60..120, 0.05);
    assert!(spec_share > 0.3, "the spec on the same depth: {spec_share}");
    // A 20 cm drop 9-10 m ahead reads as a hazard along its edge.
    let edge_row = 92;
    let drop = ground(
        &k,
        (600, 120),
        (1.65, 0.0),
        (edge_row, 0.2),
        |_, y| y % 5 == 0,
        noise,
    );
    let t = estimate(&k, &drop, Some(&lidar));
    let (hit, n) = share_at_least(&t.roughness_m, edge_row - 3..edge_row + 3, 0.05);
    assert!(
        n > 100 && hit > 0.9,
        "the drop's edge: {hit} of {n} read >= 5 cm"
    );
}

#[test]
fn dense_noisy_floor_is_flat_and_holes_are_not_steps() {
    let k = Intrinsics::new(525.0, 525.0, 160.0, 120.0).unwrap();
    let kinect = SensorNoise::Preset(SensorPreset::KinectV1);
    let hole = |x: usize, y: usize| !((100..140).contains(&x) && (150..170).contains(&y));
    let noise = |z: f64, x: usize, y: usize| kinect.sigma_z_m(z) * gauss(x, y);
    let floor = ground(&k, (320, 240), (1.0, 45.0), (0, 0.0), hole, noise);
    let t = estimate(&k, &floor, Some(&kinect));
    let (share, n) = share_at_least(&t.roughness_m, 0..240, 0.01);
    assert!(n > 50_000 && share < 0.001, "{share} of {n} read >= 1 cm");
    assert!(t.roughness_m[(120, 160)].is_nan(), "a hole has no estimate");
    // The normals face the camera and are the floor's within 3 degrees.
    let up = Vec3::new(
        0.0,
        -(45f64.to_radians().cos()),
        -(45f64.to_radians().sin()),
    );
    let n = t.normals[(60, 200)];
    assert!(n.dot(&up) > 3f64.to_radians().cos(), "{n:?}");
    // The uncertainty is the noise margin: millimetres at these ranges.
    assert!(
        t.uncertainty_m[(60, 200)] < 0.005,
        "{}",
        t.uncertainty_m[(60, 200)]
    );
}

#[test]
fn a_step_on_dense_depth_reads_as_a_hazard_and_exact_depth_stays_exact() {
    let k = Intrinsics::new(525.0, 525.0, 160.0, 120.0).unwrap();
    let depth = ground(
        &k,
        (320, 240),
        (1.0, 45.0),
        (120, 0.1),
        |_, _| true,
        |_, _, _| 0.0,
    );
    let t = estimate(&k, &depth, None);
    let (hit, _) = share_at_least(&t.roughness_m, 119..122, 0.05);
    assert!(hit > 0.95, "the step's edge: {hit}");
    let (far, n) = share_at_least(&t.roughness_m, 200..240, 1e-6);
    assert!(
        n > 0 && far == 0.0,
        "exact flat ground away from the step: {far}"
    );
}

#[test]
fn registration_layers_are_flat_but_uncertain() {
    // Accumulated LiDAR: each scan line offset by a sweep's registration error.
    let k = Intrinsics::new(721.5, 721.5, 300.0, 40.0).unwrap();
    let acc = SensorNoise::Preset(SensorPreset::LidarAccumulated);
    let layer = |z: f64, x: usize, y: usize| {
        let sweep = (y % 3) as f64 - 1.0;
        acc.registration_m(z) * sweep * 8.0 + 0.02 * gauss(x, y)
    };
    let d = ground(
        &k,
        (600, 120),
        (1.65, 0.0),
        (0, 0.0),
        |x, y| (x + y) % 2 == 0,
        layer,
    );
    let t = estimate(&k, &d, Some(&acc));
    let (share, n) = share_at_least(&t.roughness_m, 60..120, 0.05);
    assert!(n > 1000 && share < 0.02, "{share} of {n}");
    let u = t.uncertainty_m[(300, 100)];
    assert!(
        u > 0.05,
        "registration makes 5 cm unresolvable at 10 m: {u}"
    );
}

#[test]
fn cleaning_removes_range_noise_keeps_a_drop_and_fills_scan_line_gaps() {
    // A D435-class camera 0.6 m up, 30° down; the ground 8 cm lower above row 60; returns on
    // three rows of four (the fourth a gap).
    let k = Intrinsics::new(300.0, 300.0, 80.0, 60.0).unwrap();
    let d435 = SensorNoise::Preset(SensorPreset::RealsenseD435);
    let noise = |z: f64, x: usize, y: usize| d435.sigma_z_m(z) * gauss(x, y);
    let (size, mount, drop) = ((160, 120), (0.6, 30.0), (60, 0.08));
    let exact = ground(&k, size, mount, drop, |_, _| true, |_, _, _| 0.0);
    let noisy = ground(&k, size, mount, drop, |_, y| y % 4 != 3, noise);
    let points = k.back_project_map(&noisy);
    let mut cleaned = PointMap::default();
    let cfg = TerrainConfig::default();
    let mut sums = SummedMoments::default();
    clean_points_into(&points, &k, Some(&d435), &cfg, &mut sums, &mut cleaned);
    // Away from the drop, the cleaned depth is nearer the exact ground than the sensor's.
    let (mut raw_err, mut clean_err, mut n) = (0.0, 0.0, 0.0);
    let (mut gaps, mut filled) = (0usize, 0usize);
    for y in (10..50).chain(72..110) {
        for x in 10..150 {
            let (q, z) = (cleaned[(x, y)], exact[(x, y)]);
            if y % 4 == 3 {
                gaps += 1;
                if is_valid_point(&q) {
                    filled += 1;
                    // A filled gap lies on the ground, within a few noise σ.
                    assert!((q.z - z).abs() < 4.0 * d435.sigma_z_m(z), "gap ({x}, {y})");
                }
                continue;
            }
            raw_err += (noisy[(x, y)] - z).powi(2);
            clean_err += (q.z - z).powi(2);
            n += 1.0;
        }
    }
    let (raw_rms, clean_rms) = ((raw_err / n).sqrt(), (clean_err / n).sqrt());
    assert!(
        clean_rms < 0.5 * raw_rms,
        "rms {clean_rms} m, raw {raw_rms} m"
    );
    assert!(
        filled as f64 > 0.9 * gaps as f64,
        "filled {filled} of {gaps} gaps"
    );
    // The drop stays: the cleaned depth still jumps between the rows either side of it.
    let (above, below) = (cleaned[(80, 58)].z, cleaned[(80, 62)].z);
    let (exact_above, exact_below) = (exact[(80, 58)], exact[(80, 62)]);
    assert!(
        (above - below).abs() > 0.5 * (exact_above - exact_below).abs(),
        "drop {above} → {below} m, exact {exact_above} → {exact_below} m"
    );
}

#[test]
fn the_middle_eigenvalue_never_exceeds_what_may_spread_allows() {
    // Covariances of points near planes, flat to isotropic, at scales from 1e-8 to 1 m².
    let mut state = 0x9e37_79b9_7f4a_7c15u64;
    let mut next = move || {
        state = state
            .wrapping_mul(6_364_136_223_846_793_005)
            .wrapping_add(1);
        (state >> 11) as f64 / (1u64 << 53) as f64
    };
    for i in 0..4096 {
        let r = nalgebra::Rotation3::from_euler_angles(next() * 6.3, next() * 6.3, next());
        let d = Vec3::new(1.0, next(), next().powi(4));
        let m = r.matrix() * nalgebra::Matrix3::from_diagonal(&d) * r.matrix().transpose();
        let m = m * 10f64.powi(-(i % 9));
        let cov: SymLanes<1> = [
            [m[(0, 0)]],
            [m[(0, 1)]],
            [m[(0, 2)]],
            [m[(1, 1)]],
            [m[(1, 2)]],
            [m[(2, 2)]],
        ];
        if let Some((_, _, l_mid)) = eigen_plane(&cov) {
            assert!(may_spread(&cov, l_mid), "{cov:?}: {l_mid}");
        }
    }
}

#[test]
fn a_halved_frame_shares_its_noise_over_the_same_angle() {
    // The same floor, 1 m below a camera pitched 45° down, at Kinect v1's own 640×480 and
    // halved to 320×240: the correlation window covers 9 px of the first, 4.5 px of the second.
    let kinect = SensorNoise::Preset(SensorPreset::KinectV1);
    assert_eq!(kinect.correlation_in((580.0, 580.0)), (9.0, 0.9));
    assert_eq!(kinect.correlation_in((290.0, 290.0)), (4.5, 0.9));
    let median_uncertainty = |scale: f64| {
        let (w, h) = ((640.0 * scale) as usize, (480.0 * scale) as usize);
        let k =
            Intrinsics::new(580.0 * scale, 580.0 * scale, w as f64 / 2.0, h as f64 / 2.0).unwrap();
        let floor = ground(
            &k,
            (w, h),
            (1.0, 45.0),
            (0, 0.0),
            |_, _| true,
            |_, _, _| 0.0,
        );
        let t = estimate(&k, &floor, Some(&kinect));
        let mut u: Vec<f64> = t
            .uncertainty_m
            .as_slice()
            .iter()
            .copied()
            .filter(|u| u.is_finite())
            .collect();
        assert!(u.len() > w * h / 2, "{} estimates", u.len());
        u.sort_by(f64::total_cmp);
        u[u.len() / 2]
    };
    let (full, half) = (median_uncertainty(1.0), median_uncertainty(0.5));
    // A support in metres holds a quarter of the points at half the size, but as many
    // correlation windows: its mean is as uncertain (with a 9 px window at both sizes, the
    // halved frame's margin was twice the full one's).
    let ratio = half / full;
    assert!(
        (0.8..1.25).contains(&ratio),
        "median uncertainty {full} m at 640x480, {half} m at 320x240"
    );
}
