//! The pipeline end to end: every mode and method on a tiny synthetic frame and on a real Kinect
//! frame, odd frame sizes, every kind of bad input, and determinism by seed.

use std::error::Error;
use std::path::{Path, PathBuf};
use std::sync::OnceLock;

use image::RgbImage;
use tre::geometry::{
    normals::{local_planes, Neighbourhood},
    Grid, Mounting,
};
use tre::model::{Models, SessionConfig};
use tre::pipeline::{
    CentroidMethod, FrameInput, GeometricMethod, Method, Mode, NormalsMethod, Pipeline,
    PipelineConfig, PipelineError,
};
use tre::synth::dataset::SynthConfig;

use crate::common::{real, synth_config};

type TestResult = Result<(), Box<dyn Error>>;

fn models() -> Result<Models, Box<dyn Error>> {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("models");
    let cfg = SessionConfig {
        intra_threads: 1,
        ..SessionConfig::default()
    };
    Ok(Models::load(&dir, &cfg)?)
}

/// A pipeline config at a small working size (the nets are fully convolutional).
fn small(mode: Mode) -> PipelineConfig {
    PipelineConfig {
        working_size: Some((64, 64)),
        ..PipelineConfig::for_mode(mode)
    }
}

/// One frame of a one-scene, one-view synthetic dataset at 64×64, generated once per process.
fn synth_frame() -> &'static (tempfile::TempDir, PathBuf) {
    static FRAME: OnceLock<(tempfile::TempDir, PathBuf)> = OnceLock::new();
    FRAME.get_or_init(|| {
        let dir = tempfile::tempdir().expect("temp dir");
        let cfg = SynthConfig {
            ply: false,
            ..synth_config(dir.path(), 1, 5, (64, 64), 1)
        };
        let manifest = tre::synth::dataset::generate(&cfg).expect("synth generates");
        let frame = dir.path().join(&manifest.scenes[0].frames[0].dir);
        (dir, frame)
    })
}

/// Reads a frame folder of `tre synth` (rgb.png, depth.png, camera.json).
fn read_synth(dir: &Path) -> Result<FrameInput, Box<dyn Error>> {
    let (cam, k) = tre::io::read_camera(&dir.join("camera.json"))?;
    Ok(FrameInput {
        rgb: Some(tre::io::read_image(&dir.join("rgb.png"))?.to_rgb8()),
        depth_m: Some(tre::io::read_depth(&dir.join("depth.png"), 1000.0)?),
        intrinsics: Some(k),
        mounting: cam.mounting()?,
        sensor: None,
    })
}

/// A real Kinect frame: RGB, registered depth and intrinsics (slambook2 ch5, frame 1).
fn real_frame() -> Result<FrameInput, Box<dyn Error>> {
    let (cam, k) = tre::io::read_camera(&real("slambook2_ch5/intrinsics.json"))?;
    Ok(FrameInput {
        rgb: Some(tre::io::read_image(&real("slambook2_ch5/color/1.png"))?.to_rgb8()),
        depth_m: Some(tre::io::read_depth(
            &real("slambook2_ch5/depth/1.png"),
            cam.depth_scale.unwrap_or(1000.0),
        )?),
        intrinsics: Some(k),
        mounting: Some(Mounting::default()),
        sensor: None,
    })
}

/// The configurations of the paper's tables, at the small working size.
fn configs() -> Vec<PipelineConfig> {
    let mut out = Vec::new();
    for mode in [Mode::Rgb, Mode::Rgbd] {
        for normals in [NormalsMethod::Ls, NormalsMethod::Dsac] {
            for (refine, centroid) in [(true, CentroidMethod::Net), (false, CentroidMethod::Window)]
            {
                out.push(PipelineConfig {
                    normals,
                    refine,
                    centroid,
                    ..small(mode)
                });
            }
        }
    }
    out.push(small(Mode::Geometric));
    out.push(PipelineConfig {
        method: Method::EndToEnd,
        ..small(Mode::Rgb)
    });
    out
}

fn finite(g: &Grid<f64>) -> usize {
    g.as_slice().iter().filter(|v| v.is_finite()).count()
}

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
        let hazards = got.as_slice().iter().filter(|&&r| r >= 0.05).count();
        assert!(
            hazards > 1000,
            "{}: drops are hazards ({hazards} px)",
            frame.name()
        );
        // The surface-only baseline misses them: its hazards are a fraction of the spec's.
        let surface = PipelineConfig {
            geometric: GeometricMethod::SurfaceOnly,
            ..cfg
        };
        let base = pipeline.run(&input, &surface)?;
        let base_hazards = base
            .roughness_m
            .as_slice()
            .iter()
            .filter(|&&r| r >= 0.05)
            .count();
        assert!(
            base_hazards * 4 < hazards,
            "{}: {base_hazards} vs {hazards}",
            frame.name()
        );
    }
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

#[test]
fn the_same_seed_gives_the_same_output() -> TestResult {
    let frame = read_synth(&synth_frame().1)?;
    let mut pipeline = Pipeline::new(Some(models()?));
    let cfg = PipelineConfig {
        seed: 42,
        ..small(Mode::Rgbd)
    };
    let a = pipeline.run(&frame, &cfg)?;
    let b = pipeline.run(&frame, &cfg)?;
    let bits = |g: &Grid<f64>| g.as_slice().iter().map(|v| v.to_bits()).collect::<Vec<_>>();
    assert_eq!(bits(&a.roughness_m), bits(&b.roughness_m));
    let (na, nb) = (a.normals().ok_or("normals")?, b.normals().ok_or("normals")?);
    assert!(na
        .as_slice()
        .iter()
        .zip(nb.as_slice())
        .all(|(p, q)| p == q || (p.x.is_nan() && q.x.is_nan())));
    Ok(())
}

#[test]
fn fewer_dsac_hypotheses_are_repeatable_and_differ_from_twelve() -> TestResult {
    let frame = read_synth(&synth_frame().1)?;
    let mut pipeline = Pipeline::new(Some(models()?));
    let with = |dsac_hypotheses| PipelineConfig {
        seed: 42,
        dsac_hypotheses,
        refine: false,
        ..small(Mode::Rgbd)
    };
    let twelve = output_bits(&pipeline.run(&frame, &with(12))?);
    let four = output_bits(&pipeline.run(&frame, &with(4))?);
    assert_eq!(four, output_bits(&pipeline.run(&frame, &with(4))?));
    assert_ne!(four, twelve);
    assert_eq!(twelve, output_bits(&pipeline.run(&frame, &with(12))?));
    let one = pipeline.run(&frame, &with(1))?;
    assert!(finite(&one.roughness_m) > 0);
    Ok(())
}

/// Every map of an output as bits (NaN included), for exact comparisons.
fn output_bits(out: &tre::pipeline::FrameOutput) -> Vec<u64> {
    let mut bits: Vec<u64> = out
        .roughness_m
        .as_slice()
        .iter()
        .map(|v| v.to_bits())
        .collect();
    if let (Some(d), Some(n)) = (out.depth_m(), out.normals()) {
        bits.extend(d.as_slice().iter().map(|v| v.to_bits()));
        bits.extend(
            n.as_slice()
                .iter()
                .flat_map(|v| v.iter().map(|c| c.to_bits())),
        );
    }
    bits.extend(out.traversable().as_slice().iter().map(|&t| u64::from(t)));
    bits
}

#[test]
fn recycled_maps_change_no_output_and_are_reused() -> TestResult {
    let synth = read_synth(&synth_frame().1)?;
    // Depth of another size, whole or with a hole: maps kept from the frames before hold
    // values where the holed one has none.
    let depth = |hole: bool| FrameInput {
        rgb: None,
        depth_m: Some(Grid::from_fn(40, 30, |x, y| {
            if hole && (10..20).contains(&x) && (5..15).contains(&y) {
                0.0
            } else {
                1.0 + 0.01 * ((x * 7 + y * 3) % 5) as f64
            }
        })),
        ..FrameInput::default()
    };
    let (whole, holed) = (depth(false), depth(true));
    let ls = |mode| PipelineConfig {
        normals: NormalsMethod::Ls,
        ..small(mode)
    };
    let window = PipelineConfig {
        centroid: CentroidMethod::Window,
        ..small(Mode::Rgbd)
    };
    let end_to_end = PipelineConfig {
        method: Method::EndToEnd,
        ..small(Mode::Rgb)
    };
    let geometric = PipelineConfig::for_mode(Mode::Geometric);
    let steps = [
        (&synth, small(Mode::Rgb)),
        (&synth, small(Mode::Rgbd)),
        (&whole, geometric),
        (&holed, geometric),
        (&synth, ls(Mode::Rgb)),
        (&synth, window),
        (&synth, end_to_end),
        (&holed, geometric),
        (&synth, geometric),
        (&synth, small(Mode::Rgb)),
    ];
    let (mut recycling, mut fresh) = (
        Pipeline::new(Some(models()?)),
        Pipeline::new(Some(models()?)),
    );
    for (i, (frame, cfg)) in steps.iter().enumerate() {
        let a = recycling.run(frame, cfg)?;
        let b = fresh.run(frame, cfg)?;
        assert_eq!(
            output_bits(&a),
            output_bits(&b),
            "step {i}: {}",
            cfg.label()
        );
        recycling.recycle(a);
    }
    roughness_lands_in_the_buffer_handed_back(&mut recycling, &holed)
}

/// The same frame again: its roughness lands in the buffer handed back (the spec's path: the
/// terrain estimate takes three maps off the shelf, in another order).
fn roughness_lands_in_the_buffer_handed_back(
    recycling: &mut Pipeline,
    holed: &FrameInput,
) -> TestResult {
    let cfg = PipelineConfig {
        geometric: GeometricMethod::Spec,
        ..PipelineConfig::for_mode(Mode::Geometric)
    };
    let a = recycling.run(holed, &cfg)?;
    let buffer = a.roughness_m.as_slice().as_ptr();
    recycling.recycle(a);
    let b = recycling.run(holed, &cfg)?;
    assert_eq!(b.roughness_m.as_slice().as_ptr(), buffer);
    Ok(())
}

#[test]
fn bad_inputs_are_clear_errors() -> TestResult {
    let mut pipeline = Pipeline::new(None);
    let rgb = RgbImage::new(8, 6);
    let frame = FrameInput {
        rgb: Some(rgb.clone()),
        depth_m: Some(Grid::new(6, 8, 1.0)),
        ..FrameInput::default()
    };
    let err = pipeline
        .run(&frame, &small(Mode::Rgbd))
        .expect_err("depth of another size");
    assert!(
        matches!(
            err,
            PipelineError::DepthSizeMismatch {
                rgb: (8, 6),
                depth: (6, 8)
            }
        ),
        "{err}"
    );
    assert!(err.to_string().contains("6×8"), "{err}");

    let err = pipeline
        .run(&frame, &small(Mode::Rgb))
        .expect_err("no models");
    assert!(matches!(err, PipelineError::ModelsRequired { .. }), "{err}");
    assert!(err.to_string().contains("depth_net"), "{err}");

    let no_depth = FrameInput {
        rgb: Some(rgb),
        ..FrameInput::default()
    };
    let err = pipeline
        .run(&no_depth, &small(Mode::Geometric))
        .expect_err("no depth");
    assert!(
        matches!(err, PipelineError::MissingInput { input: "depth", .. }),
        "{err}"
    );

    let empty = FrameInput {
        rgb: Some(RgbImage::new(0, 4)),
        ..FrameInput::default()
    };
    let e2e = PipelineConfig {
        method: Method::EndToEnd,
        ..small(Mode::Rgb)
    };
    let err = Pipeline::new(Some(models()?))
        .run(&empty, &e2e)
        .expect_err("empty");
    assert!(matches!(err, PipelineError::EmptyImage { .. }), "{err}");
    Ok(())
}

#[test]
fn bad_settings_are_clear_errors() -> TestResult {
    let mut pipeline = Pipeline::new(None);
    let depth_only = FrameInput {
        depth_m: Some(Grid::new(100, 100, 1.0)),
        ..FrameInput::default()
    };
    let tiny_limit = PipelineConfig {
        max_input_pixels: 5000,
        ..small(Mode::Geometric)
    };
    let err = pipeline
        .run(&depth_only, &tiny_limit)
        .expect_err("too large");
    assert!(matches!(err, PipelineError::TooLarge { .. }), "{err}");

    for dsac_hypotheses in [0, 65] {
        let cfg = PipelineConfig {
            dsac_hypotheses,
            ..small(Mode::Geometric)
        };
        let err = pipeline.run(&depth_only, &cfg).expect_err("hypotheses");
        assert!(
            matches!(err, PipelineError::BadHypotheses { got } if got == dsac_hypotheses),
            "{err}"
        );
        assert!(err.to_string().contains("1 to 64"), "{err}");
    }

    let mut with_models = Pipeline::new(Some(models()?));
    let odd = PipelineConfig {
        working_size: Some((60, 64)),
        ..PipelineConfig::for_mode(Mode::Rgb)
    };
    let frame = FrameInput {
        rgb: Some(RgbImage::new(8, 6)),
        ..FrameInput::default()
    };
    let err = with_models
        .run(&frame, &odd)
        .expect_err("60 is not a multiple of 16");
    assert!(
        matches!(
            err,
            PipelineError::BadWorkingSize {
                stride: Some(16),
                ..
            }
        ),
        "{err}"
    );
    Ok(())
}

/// The digest (`tre::geometry::hash::digest`) of a map's values as `bits` gives them, in hex.
fn digest<T>(grid: &Grid<T>, bits: impl Fn(&T) -> u64) -> String {
    let h = tre::geometry::hash::digest(grid.as_slice().iter().map(bits));
    format!("{h:016x}")
}

/// An f64's bits, one NaN for all (`tre::geometry::hash::f64_bits`).
fn f64_bits(v: &f64) -> u64 {
    tre::geometry::hash::f64_bits(*v)
}

/// The geometric mode's outputs on the real frames, the roughness, the LS normals, and the
/// Kinect v1 sensor maps (uncertainty and three-state), bit for bit as in
/// `tests/fixtures/geometric_digests.json`: a change made for speed must not move one bit
/// (`TRE_WRITE_DIGESTS=1` writes the file anew, for a change that means to change outputs).
/// The ten frames of `real-rgbd` and the first of each set of `real-rgbd-2` (Kinect, LiDAR,
/// tunnel), at their own sizes.
#[test]
fn geometric_outputs_keep_their_committed_digests() -> TestResult {
    crate::common::skip_unless_shared!("data/real-rgbd", Ok(()));
    crate::common::skip_unless_shared!("data/real-rgbd-2", Ok(()));
    let mut frames = tre::eval::real::find_frames(&real(""), None)?;
    let second = crate::common::shared_root().join("data/real-rgbd-2");
    let mut sets: Vec<PathBuf> = std::fs::read_dir(&second)?
        .map(|e| e.map(|e| e.path()))
        .collect::<Result<_, _>>()?;
    sets.retain(|p| p.join("intrinsics.json").is_file());
    sets.sort();
    for set in &sets {
        frames.extend(tre::eval::real::find_frames(set, Some(1))?);
    }
    assert!(frames.len() >= 20, "{} frames", frames.len());
    let mut pipeline = Pipeline::new(None);
    // The spec's path, which these digests hold still (the terrain estimate is scored against
    // the regions in tests/it/regions.rs).
    let cfg = PipelineConfig {
        geometric: GeometricMethod::Spec,
        ..PipelineConfig::for_mode(Mode::Geometric)
    };
    let kinect =
        tre::roughness::noise::SensorNoise::Preset(tre::roughness::noise::SensorPreset::KinectV1);
    let mut got = serde_json::Map::new();
    for frame in &frames {
        let loaded = tre::eval::real::load_frame(frame)?;
        let input = FrameInput {
            rgb: None,
            ..loaded.input
        };
        let out = pipeline.run(&input, &cfg)?;
        let maps = out.sensor_maps(&input, Mode::Geometric, Some(&kinect), None, None)?;
        let normals = out.normals().ok_or("the geometric mode has normals")?;
        let entry = serde_json::json!({
            "roughness": digest(&out.roughness_m, f64_bits),
            "normals": digest(&normals, |n| n.iter().fold(0, |a, v| a.rotate_left(21) ^ f64_bits(v))),
            "uncertainty": digest(&maps.uncertainty_m, f64_bits),
            "traversal": digest(&maps.traversal, |t| *t as u64),
        });
        got.insert(frame.name(), entry);
    }
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/fixtures/geometric_digests.json");
    if std::env::var("TRE_WRITE_DIGESTS").is_ok_and(|v| v == "1") {
        let text = serde_json::to_string_pretty(&serde_json::Value::Object(got))?;
        std::fs::write(&path, text + "\n")?;
        return Ok(());
    }
    let want: serde_json::Map<String, serde_json::Value> =
        serde_json::from_slice(&std::fs::read(&path)?)?;
    for (name, digests) in &got {
        assert_eq!(Some(digests), want.get(name), "{name}: outputs moved");
    }
    assert_eq!(got.len(), want.len(), "frames digested");
    Ok(())
}
