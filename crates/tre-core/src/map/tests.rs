use super::*;

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
fn outliers_do_not_drag_a_cell_and_three_in_a_row_restart_it() {
    let c = cfg();
    let mut cell = Cell::default();
    cell.fuse_height(0.0, 1e-4, 0.0, &c);
    cell.fuse_height(0.0, 1e-4, 1.0, &c);
    // σ of the innovation: √(5e-5 + 1e-4) ≈ 1.2 cm; 10 cm is far beyond 3σ.
    assert_eq!(cell.fuse_height(0.10, 1e-4, 2.0, &c), Fused::Outlier);
    assert_eq!(cell.height_m, 0.0);
    assert_eq!(cell.fuse_height(0.10, 1e-4, 3.0, &c), Fused::Outlier);
    // A good measurement in between resets the run.
    assert_eq!(cell.fuse_height(0.001, 1e-4, 4.0, &c), Fused::Updated);
    for t in 5..7 {
        assert_eq!(
            cell.fuse_height(0.30, 1e-4, f64::from(t), &c),
            Fused::Outlier
        );
    }
    assert_eq!(cell.fuse_height(0.30, 1e-4, 7.0, &c), Fused::Started);
    assert!((cell.height_m - 0.30).abs() < 1e-6 && cell.count == 1);
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
                map.cells[i].add_roughness(0.001, 10.0);
            }
        }
    }
    let layers = map.layers(&MapLimits::default());
    // World cell (2, 7) is column 2, row 10 − 1 − 7 = 2.
    assert_eq!(layers.elevation[(2, 2)], 0.2);
    assert_eq!(layers.elevation.as_slice()[2 * 10 + 2], 0.2);
    assert_eq!(layers.traversal[(2, 2)], 2.0);
    // Its neighbours see the step; cells two away are flat and traversable.
    assert!((layers.step[(3, 2)] - 0.2).abs() < 1e-6);
    assert_eq!(layers.traversal[(3, 2)], 2.0);
    assert_eq!(layers.traversal[(6, 6)], 1.0);
    assert_eq!(layers.score[(6, 6)], 0.98);
    assert!(layers.slope[(6, 6)].abs() < 1e-6);
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
        .fuse(&points, None, &Pose::identity(), 0.0, |_| 0.002)
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
    map.fuse(&floor, None, &Pose::identity(), 0.0, |_| 0.01)
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
        map.fuse(&empty, None, &Pose::identity(), 0.0, |_| 0.01),
        Err(MapError::NothingSeen)
    );
    let far = Pose {
        translation: Vec3::new(50.0, 0.0, 0.0),
        ..Pose::identity()
    };
    let points = Grid::new(4, 4, Vec3::new(0.0, 0.0, 1.0));
    assert!(matches!(
        map.fuse(&points, None, &far, 0.0, |_| 0.01),
        Err(MapError::TooFar { .. })
    ));
    assert_eq!(state(&map), before);
}
