use super::*;
use crate::geometry::{Grid, Vec3};
use crate::roughness::noise::SensorNoise;

/// A depth sensor of `mm` millimetres of noise at every depth.
fn noise(mm: f64) -> SensorNoise {
    SensorNoise::coefficients([mm, 0.0, 0.0]).unwrap()
}
use nalgebra::{Matrix3, Matrix4};

fn cfg() -> MapConfig {
    MapConfig {
        process_var_per_s: 0.0,
        side: 10,
        cell_m: 0.1,
        ..MapConfig::default()
    }
}

fn level() -> MapFrame {
    MapFrame {
        map_from_world: Matrix3::identity(),
    }
}

#[test]
fn the_kalman_update_matches_hand_computed_values() {
    let c = MapConfig {
        process_var_per_s: 0.01,
        ..cfg()
    };
    let mut cell = Cell::default();
    assert_eq!(cell.fuse_height(0.50, 0.0004, 10.0, &c), Fused::Started);
    // 2 s later: P = 0.0004 + 0.01·2 = 0.0204; R = 0.0004; S = 0.0208; K = 0.980769…;
    // d = 0.1; h = 0.5 + 0.0980769 = 0.5980769; P = (1 − K)·P = 0.000392308.
    assert_eq!(cell.fuse_height(0.60, 0.0004, 12.0, &c), Fused::Updated);
    assert!(
        (f64::from(cell.height_m) - 0.598_076_9).abs() < 1e-6,
        "{cell:?}"
    );
    assert!(
        (f64::from(cell.var_m2) - 0.000_392_308).abs() < 1e-9,
        "{cell:?}"
    );
    assert_eq!((cell.count, cell.last_s), (2, 12.0));
}

#[test]
fn a_surface_above_goes_to_the_upper_layer_and_three_below_in_a_row_restart_the_ground() {
    let c = cfg();
    let mut cell = Cell::default();
    cell.fuse_height(0.0, 1e-4, 0.0, &c);
    cell.fuse_height(0.0, 1e-4, 1.0, &c);
    // σ of the innovation: √(5e-5 + 1e-4) ≈ 1.2 cm; 10 cm above is another surface.
    assert_eq!(cell.fuse_height(0.10, 1e-4, 2.0, &c), Fused::Above);
    assert_eq!(
        (cell.height_m, cell.upper_m, cell.upper_count),
        (0.0, 0.10, 1)
    );
    // Below the ground: outliers; a good measurement in between resets the run.
    assert_eq!(cell.fuse_height(-0.10, 1e-4, 3.0, &c), Fused::Outlier);
    assert_eq!(cell.fuse_height(0.001, 1e-4, 4.0, &c), Fused::Updated);
    for t in 5..7 {
        assert_eq!(
            cell.fuse_height(-0.30, 1e-4, f64::from(t), &c),
            Fused::Outlier
        );
    }
    // The third in a row: the ground was a surface above the real one. The upper surface
    // stays the highest seen.
    assert_eq!(cell.fuse_height(-0.30, 1e-4, 7.0, &c), Fused::Started);
    assert!((cell.height_m + 0.30).abs() < 1e-6 && cell.count == 1);
    assert!((cell.upper_m - 0.10).abs() < 1e-6, "{cell:?}");
    assert!((cell.clearance_m() - 0.40).abs() < 1e-6);
}

#[test]
fn recentring_clears_only_the_cells_that_leave_and_keeps_the_rest_in_place() {
    let mut map = GridMap::new(cfg(), level(), (0.0, 0.0)).unwrap();
    assert_eq!(map.origin(), (-5, -5));
    let c = *map.config();
    for ix in -5..5 {
        for iy in -5..5 {
            let i = map.slot(ix, iy).unwrap();
            map.cells[i].fuse_height(ix as f64 + 10.0 * iy as f64, 1e-4, 0.0, &c);
        }
    }
    // Two cells east and one north: columns −5, −4 and row −5 leave (10 + 10 + 8 = 28 cells).
    let cleared = map.recentre((0.2, 0.1));
    assert_eq!(map.origin(), (-3, -4));
    assert_eq!(cleared, 28);
    for ix in -3..7 {
        for iy in -4..6 {
            let cell = map.cell(ix, iy).unwrap();
            if ix < 5 && iy < 5 {
                assert_eq!(
                    cell.height_m,
                    (ix as f64 + 10.0 * iy as f64) as f32,
                    "{ix},{iy}"
                );
            } else {
                assert_eq!(cell.count, 0, "{ix},{iy} should be new");
            }
        }
    }
    assert!(map.cell(-4, 0).is_none());
    // A jump beyond the window clears it all.
    assert_eq!(map.recentre((100.0, 100.0)), 100);
}

#[test]
fn layers_are_row_major_with_north_up_and_judge_steps() {
    let mut map = GridMap::new(cfg(), level(), (0.5, 0.5)).unwrap();
    assert_eq!(map.origin(), (0, 0));
    let c = *map.config();
    // A floor at 0 with one raised cell at world cell (2, 7), seen three times each.
    for t in 0..3 {
        for ix in 0..10 {
            for iy in 0..10 {
                let z = if (ix, iy) == (2, 7) { 0.2 } else { 0.0 };
                let i = map.slot(ix, iy).unwrap();
                map.cells[i].fuse_height(z, 1e-6, f64::from(t), &c);
            }
        }
    }
    let layers = map.layers(&MapLimits::default());
    // World cell (2, 7) is column 2, row 10 − 1 − 7 = 2.
    assert_eq!(layers.elevation[(2, 2)], 0.2);
    assert_eq!(layers.elevation.as_slice()[2 * 10 + 2], 0.2);
    // The raised cell stands 20 cm above its neighbours (less 2σ of the difference).
    assert!(
        (layers.step[(2, 2)] - 0.2).abs() < 0.003,
        "{}",
        layers.step[(2, 2)]
    );
    assert_eq!(layers.traversal[(2, 2)], 2.0);
    // The floor beside it is not poisoned: its neighbourhood leaves the other surface out.
    assert_eq!(layers.step[(3, 2)], 0.0);
    assert_eq!(layers.roughness[(3, 2)], 0.0);
    assert_eq!(layers.traversal[(3, 2)], 1.0);
    assert_eq!(layers.traversal[(6, 6)], 1.0);
    assert_eq!(layers.score[(6, 6)], 1.0);
    assert!(layers.slope[(6, 6)].abs() < 1e-6);
}

/// A window of `side` cells of 10 cm whose every cell holds the height `h(ix, iy)` fused
/// `frames` times with variance `var`.
fn surface_map(side: usize, frames: u32, var: f64, h: impl Fn(i64, i64) -> f64) -> GridMap {
    let cfg = MapConfig {
        side,
        roughness_radius_m: 0.2,
        ..cfg()
    };
    let mut map = GridMap::new(cfg, level(), (0.0, 0.0)).unwrap();
    let (ox, oy) = map.origin();
    for t in 0..frames {
        for ix in ox..ox + side as i64 {
            for iy in oy..oy + side as i64 {
                let i = map.slot(ix, iy).unwrap();
                map.cells[i].fuse_height(h(ix, iy), var, f64::from(t), &cfg);
            }
        }
    }
    map
}

#[test]
fn roughness_comes_from_the_fused_surface_less_what_the_variances_explain() {
    // A deterministic pseudo-random field of ±3 cm bumps on a 10° slope: the roughness is
    // the bumps' scatter, the slope the plane's.
    let bump = |ix: i64, iy: i64| {
        let mut v = (ix * 1_000_003 + iy) as u64;
        v ^= v >> 33;
        v = v.wrapping_mul(0xff51_afd7_ed55_8ccd);
        v ^= v >> 33;
        (v % 1001) as f64 / 1000.0 * 0.06 - 0.03
    };
    let tilt = 10f64.to_radians().tan();
    let rough = surface_map(30, 4, 1e-6, |ix, iy| tilt * ix as f64 * 0.1 + bump(ix, iy));
    let l = rough.layers(&MapLimits::default());
    let r = l.roughness[(15, 15)];
    // A uniform ±3 cm field has σ = 0.06/√12 = 1.73 cm.
    assert!((0.012..0.023).contains(&r), "{r}");
    assert!(
        (l.slope[(15, 15)] - 10.0).abs() < 1.5,
        "{}",
        l.slope[(15, 15)]
    );
    // A level floor whose heights carry only the noise their variance states reads smooth:
    // one frame of ±1.7 cm noise stated as σ = 1 cm·… is what the variances explain.
    let noisy = surface_map(30, 1, 0.0001, |ix, iy| bump(ix, iy) / 3.0);
    let r = noisy.layers(&MapLimits::default()).roughness[(15, 15)];
    assert!(r < 0.004, "noise alone read as {r} m of roughness");
}

#[test]
fn one_frame_of_a_level_floor_makes_a_robot_centred_map() {
    // A camera 1 m up looking straight down at a level floor: with the identity pose, the
    // camera frame is the world; the map frame turns the camera's −z (towards the floor) down.
    let frame = MapFrame::from_gravity(&Vec3::new(0.0, 0.0, 1.0)).unwrap();
    let mut map = GridMap::new(cfg(), frame, (0.0, 0.0)).unwrap();
    let points = Grid::from_fn(40, 40, |x, y| {
        Vec3::new(x as f64 * 0.02 - 0.4, y as f64 * 0.02 - 0.4, 1.0)
    });
    let stats = map
        .fuse(&points, &Pose::identity(), 0.0, &noise(2.0))
        .unwrap();
    assert_eq!(stats.points, 1600);
    assert_eq!(stats.started, stats.cells);
    let seen: Vec<f32> = map
        .cells
        .iter()
        .filter(|c| c.count > 0)
        .map(|c| c.height_m)
        .collect();
    assert_eq!(seen.len(), 64);
    // The floor is 1 m below the camera in the map frame.
    assert!(seen.iter().all(|h| (h + 1.0).abs() < 1e-6), "{seen:?}");
}

#[test]
fn bad_input_leaves_the_map_as_it_was() {
    let mut m = Matrix4::identity();
    m[(0, 1)] = 0.5;
    assert!(matches!(
        Pose::from_matrix(&m),
        Err(MapError::NotRigid { .. })
    ));
    let mut map = GridMap::new(cfg(), level(), (0.0, 0.0)).unwrap();
    let floor = Grid::new(4, 4, Vec3::new(0.05, 0.05, 1.0));
    map.fuse(&floor, &Pose::identity(), 0.0, &noise(10.0))
        .unwrap();
    let state = |m: &GridMap| -> Vec<(u32, u32)> {
        m.cells
            .iter()
            .map(|c| (c.count, c.height_m.to_bits()))
            .collect()
    };
    let before = state(&map);
    let empty = Grid::new(4, 4, crate::geometry::INVALID_POINT);
    assert_eq!(
        map.fuse(&empty, &Pose::identity(), 0.0, &noise(10.0)),
        Err(MapError::NothingSeen)
    );
    let far = Pose {
        translation: Vec3::new(50.0, 0.0, 0.0),
        ..Pose::identity()
    };
    let points = Grid::new(4, 4, Vec3::new(0.0, 0.0, 1.0));
    assert!(matches!(
        map.fuse(&points, &far, 0.0, &noise(10.0)),
        Err(MapError::TooFar { .. })
    ));
    assert_eq!(state(&map), before);
}

/// Points of a camera 1 m above a level floor looking straight down (identity pose, the map
/// frame turning the camera's +z down): a 40 × 40 patch of floor, and, in the cells with
/// x < 0, a counter top 0.5 m above it over a quarter of the points.
fn floor_and_counter(counter: bool) -> Grid<Vec3> {
    Grid::from_fn(40, 40, |x, y| {
        let (px, py) = (x as f64 * 0.02 - 0.4, y as f64 * 0.02 - 0.4);
        let top = counter && px < 0.0 && x % 2 == 0;
        Vec3::new(px, py, if top { 0.5 } else { 1.0 })
    })
}

#[test]
fn a_counter_over_the_floor_keeps_the_floor_as_ground_in_any_frame_order() {
    let frame = MapFrame::from_gravity(&Vec3::new(0.0, 0.0, 1.0)).unwrap();
    let run = |order: &[bool]| -> Vec<(f32, u32)> {
        let mut map = GridMap::new(cfg(), frame, (0.0, 0.0)).unwrap();
        for (t, &counter) in order.iter().enumerate() {
            map.fuse(
                &floor_and_counter(counter),
                &Pose::identity(),
                t as f64,
                &noise(2.0),
            )
            .unwrap();
        }
        map.cells
            .iter()
            .filter(|c| c.count > 0)
            .map(|c| (c.height_m, c.upper_m.to_bits()))
            .collect()
    };
    let a = run(&[true, true, false, false]);
    let b = run(&[false, false, true, true]);
    assert_eq!(a.len(), 64);
    // The ground is the floor everywhere (1 m below the camera; the counter does not pull
    // it up), and the cells under the counter hold it as their upper surface, 0.5 m above.
    assert!(a.iter().all(|(h, _)| (h + 1.0).abs() < 1e-3), "{a:?}");
    let upper: Vec<f32> = a
        .iter()
        .map(|&(_, u)| f32::from_bits(u))
        .filter(|u| u.is_finite())
        .collect();
    assert_eq!(upper.len(), 32, "{a:?}");
    assert!(upper.iter().all(|u| (u + 0.5).abs() < 1e-3), "{upper:?}");
    assert_eq!(a, b);
}

#[test]
fn a_settings_file_starts_from_its_preset_and_is_checked() {
    let file = MapParamsFile {
        preset: Some(MapPreset::Outdoor),
        grid: GridKeys {
            cell_m: Some(0.2),
            size_m: None,
        },
        ..MapParamsFile::default()
    };
    let p = MapParams::from_file(&file).unwrap();
    assert_eq!(
        (p.config.cell_m, p.config.side, p.config.max_range_m),
        (0.2, 400, 20.0)
    );
    let bad = MapParamsFile {
        range: RangeKeys {
            min_m: Some(5.0),
            max_m: Some(3.0),
        },
        ..MapParamsFile::default()
    };
    assert!(matches!(
        MapParams::from_file(&bad),
        Err(ParamsError::OutOfRange {
            key: "range.max_m",
            ..
        })
    ));
}
