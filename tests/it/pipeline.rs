//! The pipeline end to end: every mode and method on a tiny synthetic frame and on a real Kinect
//! frame, odd frame sizes, every kind of bad input, and determinism by seed. Here: the frames
//! and configurations the tests share, and the geometric mode's outputs held bit for bit by
//! their committed digests.

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

mod bad_input;
mod modes;
mod repeat;

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

/// Pixels of `roughness` at 5 cm or more (the spec's hazard threshold).
fn hazards(roughness: &Grid<f64>) -> usize {
    roughness.as_slice().iter().filter(|&&r| r >= 0.05).count()
}

/// Of the pixels without depth in `depth`, how many there are and how many `roughness`
/// reads; and how many pixels with depth it reads.
fn holes_read(roughness: &Grid<f64>, depth: &Grid<f64>) -> (usize, usize, usize) {
    roughness.as_slice().iter().zip(depth.as_slice()).fold(
        (0, 0, 0),
        |(holes, holes_read, read), (&r, &d)| {
            let reads = usize::from(r.is_finite());
            if d > 0.0 {
                (holes, holes_read, read + reads)
            } else {
                (holes + 1, holes_read + reads, read)
            }
        },
    )
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
