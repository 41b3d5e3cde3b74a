//! The uncertainty map's prediction against annotation spec v1 run on simulated noisy planes.

use super::*;

/// SplitMix64: a deterministic stream of uniform numbers for the simulated noise.
struct Rng(u64);

impl Rng {
    fn uniform(&mut self) -> f64 {
        self.0 = self.0.wrapping_add(0x9e37_79b9_7f4a_7c15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
        ((z ^ (z >> 31)) >> 11) as f64 / (1u64 << 53) as f64
    }

    /// A standard normal number (Box–Muller).
    fn normal(&mut self) -> f64 {
        let u = self.uniform().max(1e-300);
        (-2.0 * u.ln()).sqrt() * (std::f64::consts::TAU * self.uniform()).cos()
    }
}

/// Depth of a plane through `(0, 0, range_m)` whose normal is tilted `tilt_deg` from the
/// optical axis (about the camera's x axis), with Gaussian depth noise σ_z(z) added.
fn noisy_plane(
    k: &Intrinsics,
    size: (usize, usize),
    range_m: f64,
    tilt_deg: f64,
    sensor: &SensorNoise,
    rng: &mut Rng,
) -> (Grid<f64>, Vec3) {
    let t = tilt_deg.to_radians();
    let n = Vec3::new(0.0, -t.sin(), -t.cos());
    let d = n.dot(&Vec3::new(0.0, 0.0, range_m));
    let depth = Grid::from_fn(size.0, size.1, |x, y| {
        let ray = Vec3::new(
            (x as f64 - k.cx_px) / k.fx_px,
            (y as f64 - k.cy_px) / k.fy_px,
            1.0,
        );
        let z = d / n.dot(&ray);
        z + sensor.sigma_z_m(z) * rng.normal()
    });
    (depth, n)
}

/// The 95th percentile of `v` (sorted in place).
fn p95(v: &mut [f64]) -> f64 {
    v.sort_by(f64::total_cmp);
    v[((v.len() as f64) * 0.95) as usize]
}

/// One row of the table: predicted and simulated p95 of the surface term and of the full
/// spec roughness over the plane's interior.
#[derive(Debug)]
struct Row {
    range_m: f64,
    tilt_deg: f64,
    surface: (f64, f64),
    full: (f64, f64),
    break_fraction: f64,
}

fn simulate(sensor: &SensorNoise, range_m: f64, tilt_deg: f64, seed: u64) -> Row {
    let size = (120, 90);
    let k = Intrinsics::new(525.0, 525.0, 59.5, 44.5).unwrap();
    let mut rng = Rng(seed);
    let (depth, _) = noisy_plane(&k, size, range_m, tilt_deg, sensor, &mut rng);
    let input = AnnotateInput::depth(&depth, &k);
    let cfg = AnnotateConfig::default();
    let ann = annotate(&input, &cfg).unwrap();
    let noise = pixel_noise_map(&depth, &k, &ann.normals, sensor, &cfg);
    // The interior: windows reach 7 px, so border pixels see one-sided windows.
    let inner =
        |(x, y): &(usize, usize)| (8..size.0 - 8).contains(x) && (8..size.1 - 8).contains(y);
    let pixels: Vec<(usize, usize)> = (0..size.1)
        .flat_map(|y| (0..size.0).map(move |x| (x, y)))
        .filter(inner)
        .collect();
    let (mut s_sim, mut r_sim, mut s_pred, mut r_pred) = (vec![], vec![], vec![], vec![]);
    let mut breaks = 0.0;
    for &p in &pixels {
        let pn = noise[p].unwrap();
        s_sim.push(ann.surface_m[p]);
        r_sim.push(ann.roughness_m[p]);
        breaks += pn.break_fraction;
        // The predicted distribution: half-normal with the predicted σ, sampled.
        let sigma = pn.surface_p95_m / tre::roughness::noise::HALF_NORMAL_P95;
        for _ in 0..16 {
            let s = (sigma * rng.normal()).abs();
            s_pred.push(s);
            r_pred.push(s.max(pn.edge_m));
        }
    }
    Row {
        range_m,
        tilt_deg,
        surface: (p95(&mut s_pred), p95(&mut s_sim)),
        full: (p95(&mut r_pred), p95(&mut r_sim)),
        break_fraction: breaks / pixels.len() as f64,
    }
}

fn table(sensor: SensorPreset) -> Vec<Row> {
    let s = SensorNoise::Preset(sensor);
    let mut rows = vec![];
    for (i, range_m) in [1.0, 2.0, 3.0, 4.0].into_iter().enumerate() {
        for (j, tilt_deg) in [0.0, 30.0, 60.0].into_iter().enumerate() {
            rows.push(simulate(
                &s,
                range_m,
                tilt_deg,
                1000 + 10 * i as u64 + j as u64,
            ));
        }
    }
    eprintln!("{sensor}: range m | tilt ° | surface p95 predicted / simulated mm (ratio) | full p95 predicted / simulated mm (ratio) | joins broken");
    for r in &rows {
        eprintln!(
            "| {:.0} | {:.0} | {:.2} | {:.2} | {:.2} | {:.2} | {:.2} | {:.2} | {:.3} |",
            r.range_m,
            r.tilt_deg,
            r.surface.0 * 1e3,
            r.surface.1 * 1e3,
            r.surface.1 / r.surface.0,
            r.full.0 * 1e3,
            r.full.1 * 1e3,
            r.full.1 / r.full.0,
            r.break_fraction
        );
    }
    rows
}

/// The prediction's domain (docs/sensor-noise.md): the surface term while the depth noise is
/// under a fifth of the radius R; the full roughness (surface and edge terms) while noise
/// breaks under 1% of the segment joins (no edge term) and once it breaks over 90% of them
/// (boundaries everywhere; at 60° tilt the prediction may overstate it by up to 35%: it is
/// conservative there). Between, and for the surface term under larger noise, the table
/// is printed but not asserted; every domain must hold some cells.
#[test]
fn noise_floor_matches_simulation_within_20_percent_in_its_domain() {
    let mut checked = [0; 3];
    for sensor in [
        SensorPreset::KinectV1,
        SensorPreset::RealsenseD435,
        SensorPreset::Lidar,
    ] {
        for r in table(sensor) {
            let surface = r.surface.1 / r.surface.0;
            let full = r.full.1 / r.full.0;
            if sensor.sigma_z_m(r.range_m) <= 0.2 * 0.05 {
                checked[0] += 1;
                assert!(
                    (0.8..=1.2).contains(&surface),
                    "{sensor} {r:?}: surface {surface:.3}"
                );
            }
            let broken = r.break_fraction >= 0.9;
            if r.break_fraction < 0.01 || broken {
                checked[usize::from(broken) + 1] += 1;
                // At 60° the prediction overstates the edge term (conservative), see the docs.
                let domain = if broken && r.tilt_deg >= 60.0 {
                    0.65..=1.2
                } else {
                    0.8..=1.2
                };
                assert!(domain.contains(&full), "{sensor} {r:?}: full {full:.3}");
            }
        }
    }
    assert!(
        checked.iter().all(|&c| c >= 3),
        "cells checked per domain: {checked:?}"
    );
}
