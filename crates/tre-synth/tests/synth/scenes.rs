//! Determinism, depth and normals against the rendered surface, camera pose and optics, the
//! annotator on flat pavement and stairs, and image effects.

use super::*;

#[test]
fn same_seed_same_bytes() {
    let (a, b, c) = (
        tempfile::tempdir().unwrap(),
        tempfile::tempdir().unwrap(),
        tempfile::tempdir().unwrap(),
    );
    tre_synth::dataset::generate(&small_config(a.path(), 5)).unwrap();
    tre_synth::dataset::generate(&small_config(b.path(), 5)).unwrap();
    tre_synth::dataset::generate(&small_config(c.path(), 6)).unwrap();
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

#[test]
fn depth_and_normals_agree_with_the_rendered_surface() {
    let cfg = SynthConfig {
        size: (160, 160),
        ..SynthConfig::default()
    };
    let views = tre_synth::dataset::scene_views(&cfg, 3);
    let scene = tre_synth::dataset::build_scene(&cfg, 3, &views);
    let (mut checked, mut worst_png_mm) = (0, 0.0f64);
    for view in [&views[0], &views[4], &views[8]] {
        let f = render(&scene, view, &clear_noon());
        let rot = view.world_from_cam();
        let png = tre_io::depth_png16(&f.depth_m);
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
    use tre_synth::dataset::OPTICS;
    let dir = tempfile::tempdir().unwrap();
    let cfg = SynthConfig {
        ply: false,
        random_optics: true,
        ..synth_config(dir.path(), 2, 11, (96, 72), 9)
    };
    tre_synth::dataset::generate(&cfg).unwrap();
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
fn image_effects_change_only_the_image_and_are_recorded() {
    let (a, b) = (tempfile::tempdir().unwrap(), tempfile::tempdir().unwrap());
    let cfg = |out: &Path, effects: Vec<ImageEffect>| SynthConfig {
        effects,
        sensors: vec![SensorPreset::KinectV1],
        ply: false,
        ..small_config(out, 8)
    };
    tre_synth::dataset::generate(&cfg(a.path(), vec![])).unwrap();
    tre_synth::dataset::generate(&cfg(b.path(), ImageEffect::ALL.to_vec())).unwrap();
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
