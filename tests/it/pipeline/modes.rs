//! Every mode and method runs: on a tiny synthetic frame, on the shared real frames (the
//! geometric mode equal to the annotator), at odd sizes and at 12 megapixels.

use super::*;

#[test]
fn every_mode_runs_on_a_synthetic_frame() -> TestResult {
    let frame = read_synth(&synth_frame().1)?;
    let mut pipeline = Pipeline::new(Some(models()?));
    let valid_depth = frame
        .depth_m
        .as_ref()
        .map_or(0, |d| d.as_slice().iter().filter(|&&z| z > 0.0).count());
    assert!(valid_depth > 1000, "the synthetic frame sees ground");
    for cfg in configs() {
        let out = pipeline.run(&frame, &cfg)?;
        let label = cfg.label();
        assert_eq!(out.roughness_m.size(), (64, 64), "{label}");
        assert_eq!(out.traversable().size(), (64, 64), "{label}");
        assert!(
            out.roughness_m
                .as_slice()
                .iter()
                .all(|r| r.is_nan() || *r >= 0.0),
            "{label}"
        );
        if cfg.method == Method::EndToEnd {
            assert!(out.normals().is_none() && out.timings.get("end_to_end").is_some());
            continue;
        }
        if cfg.is_terrain() {
            assert!(out.timings.get("terrain").is_some(), "{label}");
            continue;
        }
        assert!(out.timings.get("normals").is_some() && out.timings.get("centroid").is_some());
        assert_eq!(
            out.timings.get("refine").is_some(),
            cfg.effective().1,
            "{label}"
        );
        if cfg.mode != Mode::Rgb {
            // Given depth: every pixel with depth has a point, and nearly all a roughness.
            assert!(finite(&out.roughness_m) + 20 >= valid_depth, "{label}");
        }
        let normals = out.normals().ok_or("normals")?;
        let unit = normals
            .as_slice()
            .iter()
            .filter(|n| n.x.is_finite())
            .all(|n| (n.norm() - 1.0).abs() < 1e-3);
        assert!(unit, "{label}: normals are unit");
    }
    Ok(())
}

#[test]
fn geometric_surface_only_is_ls_normals_and_window_centroids_at_the_frame_size() -> TestResult {
    let frame = read_synth(&synth_frame().1)?;
    let mut pipeline = Pipeline::new(None);
    let cfg = PipelineConfig {
        geometric: GeometricMethod::SurfaceOnly,
        ..PipelineConfig::for_mode(Mode::Geometric)
    };
    let out = pipeline.run(&frame, &cfg)?;
    let k = frame.intrinsics.ok_or("intrinsics")?;
    let points = k.back_project_map(frame.depth_m.as_ref().ok_or("depth")?);
    let planes = local_planes(&points, k.fx_px, &Neighbourhood::default());
    for y in 0..64 {
        for x in 0..64 {
            let want = planes.normal[(x, y)]
                .dot(&(points[(x, y)] - planes.centroid[(x, y)]))
                .abs();
            let got = out.roughness_m[(x, y)];
            assert!(
                got == want || (got.is_nan() && want.is_nan()),
                "({x}, {y}): {got} vs {want}"
            );
        }
    }
    assert_eq!(out.working_size, (64, 64));
    Ok(())
}

#[test]
fn geometric_mode_is_the_annotator_on_every_shared_real_frame() -> TestResult {
    crate::common::skip_unless_shared!("data/real-rgbd", Ok(()));
    // The spec (`tre annotate` without labels) and the geometric mode at the frame's own size
    // must agree bit for bit: one implementation serves both.
    let frames = tre::eval::real::find_frames(&real(""), None)?;
    assert_eq!(frames.len(), 10, "the shared real frames");
    let mut pipeline = Pipeline::new(None);
    let cfg = PipelineConfig {
        geometric: GeometricMethod::Spec,
        ..PipelineConfig::for_mode(Mode::Geometric)
    };
    assert_eq!(cfg.label(), "LS+window+edge");
    for frame in &frames {
        let loaded = tre::eval::real::load_frame(frame)?;
        let input = FrameInput {
            rgb: None,
            ..loaded.input.clone()
        };
        let out = pipeline.run(&input, &cfg)?;
        let (got, want) = (&out.roughness_m, &loaded.spec.roughness_m);
        assert_eq!(got.size(), want.size());
        let differ = got
            .as_slice()
            .iter()
            .zip(want.as_slice())
            .filter(|(a, b)| a.to_bits() != b.to_bits() && !(a.is_nan() && b.is_nan()))
            .count();
        assert_eq!(
            differ,
            0,
            "{}: pixels that differ from the spec",
            frame.name()
        );
        let spec_hazards = hazards(got);
        assert!(
            spec_hazards > 1000,
            "{}: drops are hazards ({spec_hazards} px)",
            frame.name()
        );
        // The surface-only baseline misses them: its hazards are a fraction of the spec's.
        let surface = PipelineConfig {
            geometric: GeometricMethod::SurfaceOnly,
            ..cfg
        };
        let base = pipeline.run(&input, &surface)?;
        let base_hazards = hazards(&base.roughness_m);
        assert!(
            base_hazards * 4 < spec_hazards,
            "{}: {base_hazards} vs {spec_hazards}",
            frame.name()
        );
    }
    Ok(())
}

#[test]
fn the_spec_on_cleaned_depth_reads_no_pixel_the_sensor_left_empty() -> TestResult {
    crate::common::skip_unless_shared!("data/real-rgbd", Ok(()));
    // The cleaning fills a hole from a nearby support's plane (for `rgbd`); the spec on
    // cleaned depth keeps it empty, since beside an edge that plane reads a drop as flat.
    let frames = tre::eval::real::find_frames(&real(""), None)?;
    let mut pipeline = Pipeline::new(None);
    let cfg = PipelineConfig {
        geometric: GeometricMethod::SpecCleaned,
        ..PipelineConfig::for_mode(Mode::Geometric)
    };
    let spec = PipelineConfig {
        geometric: GeometricMethod::Spec,
        ..cfg
    };
    let (mut cleaned_hazards, mut spec_hazards) = (0, 0);
    for frame in &frames {
        let loaded = tre::eval::real::load_frame(frame)?;
        let input = FrameInput {
            rgb: None,
            sensor: Some(tre::roughness::noise::SensorNoise::Preset(
                tre::roughness::noise::SensorPreset::KinectV1,
            )),
            ..loaded.input.clone()
        };
        let depth = input.depth_m.as_ref().ok_or("depth")?;
        let out = pipeline.run(&input, &cfg)?;
        assert!(out.timings.get("clean").is_some());
        let (holes, holes_read, read) = holes_read(&out.roughness_m, depth);
        assert_eq!(holes_read, 0, "{}: holes read", frame.name());
        assert!(
            holes > 0 && read > 100_000,
            "{}: {holes} holes, {read} read",
            frame.name()
        );
        cleaned_hazards += hazards(&out.roughness_m);
        let raw = pipeline.run(&input, &spec)?;
        spec_hazards += hazards(&raw.roughness_m);
    }
    // Most of what the spec calls a hazard is a real edge on these frames, and stays.
    assert!(
        2 * cleaned_hazards > spec_hazards,
        "{cleaned_hazards} hazard px cleaned, {spec_hazards} raw"
    );
    Ok(())
}

#[test]
fn rgbd_reads_no_hole_a_camera_left() -> TestResult {
    crate::common::skip_unless_shared!("data/real-rgbd-2", Ok(()));
    use tre::roughness::noise::{SensorNoise, SensorPreset};
    // The cleaning fills a hole from a nearby support's plane; beside an edge (a Kinect's
    // shadow) that reads a drop as flat, so a camera's holes stay empty. Resampled to the
    // nets' working size they always were (`keep_holes`); at the frame's own size the
    // cleaning's filled points would reach the output.
    let mut pipeline = Pipeline::new(Some(models()?));
    let dir = crate::common::shared_root().join("data/real-rgbd-2/open3d_tum");
    let frame = tre::eval::real::find_frames(&dir, None)?
        .into_iter()
        .next()
        .ok_or("no frame")?;
    let loaded = tre::eval::real::load_frame(&frame)?;
    let input = FrameInput {
        sensor: Some(SensorNoise::Preset(SensorPreset::KinectV1)),
        ..loaded.input.clone()
    };
    let depth = input.depth_m.as_ref().ok_or("depth")?;
    let cfg = PipelineConfig {
        working_size: Some(depth.size()),
        ..PipelineConfig::for_mode(Mode::Rgbd)
    };
    let out = pipeline.run(&input, &cfg)?;
    assert_eq!(out.working_size, depth.size());
    assert!(out.timings.get("clean").is_some());
    let (holes, holes_read, _) = holes_read(&out.roughness_m, depth);
    assert!(holes > 1000, "{holes} holes");
    assert_eq!(holes_read, 0, "holes read");
    Ok(())
}

#[test]
fn every_mode_runs_on_a_real_frame() -> TestResult {
    crate::common::skip_unless_shared!("data/real-rgbd", Ok(()));
    let frame = real_frame()?;
    let mut pipeline = Pipeline::new(Some(models()?));
    for mode in [Mode::Rgb, Mode::Rgbd, Mode::Geometric] {
        let out = pipeline.run(&frame, &PipelineConfig::for_mode(mode))?;
        assert_eq!(out.roughness_m.size(), (640, 480), "{mode:?}");
        assert!(finite(&out.roughness_m) > 100_000, "{mode:?}");
        // Networks run at 256 on the long side with the frame's 4:3 aspect kept.
        let expected = if mode == Mode::Geometric {
            (640, 480)
        } else {
            (256, 192)
        };
        assert_eq!(out.working_size, expected);
    }
    // Holes in the sensor's depth stay holes in rgbd and geometric modes, at the frame's size:
    // in rgbd, run at 256×192, a hole's nearest working pixel may have had depth.
    let depth = frame.depth_m.as_ref().ok_or("depth")?;
    let holes: Vec<usize> = (depth.as_slice().iter().enumerate())
        .filter(|(_, &z)| z <= 0.0)
        .map(|(i, _)| i)
        .collect();
    assert!(holes.len() > 1000, "the frame has holes");
    for mode in [Mode::Geometric, Mode::Rgbd] {
        let out = pipeline.run(&frame, &PipelineConfig::for_mode(mode))?;
        let traversable = out.traversable();
        let boundary = out.boundary().ok_or("boundary")?;
        for &i in &holes {
            assert!(out.roughness_m.as_slice()[i].is_nan(), "{mode:?} at {i}");
            assert!(!traversable.as_slice()[i], "{mode:?} at {i}");
            assert!(!boundary.as_slice()[i], "{mode:?} boundary at {i}");
        }
    }
    Ok(())
}

#[test]
fn odd_sizes_work() -> TestResult {
    let mut pipeline = Pipeline::new(Some(models()?));
    for (w, h) in [(1, 1), (7, 5), (1242, 375)] {
        let rgb = RgbImage::from_fn(w as u32, h as u32, |x, y| {
            image::Rgb([(x % 256) as u8, (y % 256) as u8, 90])
        });
        let depth = Grid::from_fn(w, h, |_, y| 1.0 + 0.01 * y as f64);
        let frame = FrameInput {
            rgb: Some(rgb),
            depth_m: Some(depth),
            intrinsics: None,
            mounting: Some(Mounting::default()),
            sensor: None,
        };
        for mode in [Mode::Rgb, Mode::Rgbd, Mode::Geometric] {
            let out = pipeline.run(&frame, &small(mode))?;
            assert_eq!(out.roughness_m.size(), (w, h), "{mode:?} {w}×{h}");
            assert_eq!(out.depth_m().as_ref().map(Grid::size), Some((w, h)));
        }
        let native = pipeline.run(&frame, &PipelineConfig::for_mode(Mode::Geometric))?;
        assert_eq!(native.working_size, (w, h));
    }
    Ok(())
}

/// A 12-megapixel frame (4000×3000) runs at 256×192 and every map comes back at full size.
#[test]
fn a_twelve_megapixel_frame_runs_at_the_working_size() -> TestResult {
    let (w, h) = (4000, 3000);
    let rgb = RgbImage::from_fn(w as u32, h as u32, |x, y| {
        image::Rgb([(x / 16 % 256) as u8, (y / 16 % 256) as u8, 90])
    });
    let frame = FrameInput {
        rgb: Some(rgb),
        depth_m: Some(Grid::from_fn(w, h, |_, y| 1.0 + 0.001 * y as f64)),
        intrinsics: None,
        mounting: Some(Mounting::default()),
        sensor: None,
    };
    let mut pipeline = Pipeline::new(Some(models()?));
    for mode in [Mode::Rgb, Mode::Rgbd] {
        let out = pipeline.run(&frame, &PipelineConfig::for_mode(mode))?;
        assert_eq!(out.working_size, (256, 192), "{mode:?}");
        assert_eq!(out.roughness_m.size(), (w, h), "{mode:?}");
        assert!(
            out.roughness_m.as_slice().iter().all(|r| r.is_finite()),
            "{mode:?}"
        );
    }
    Ok(())
}
