//! `tre map`: a sequence of depth frames (with their poses) fused into the robot's grid map,
//! written layer by layer (docs/map.md).

use std::path::PathBuf;
use std::time::Instant;

use anyhow::Context;
use clap::Args;

use crate::geometry::Vec3;
use crate::io::map_files::{write_map, CameraMark, MapRun, MapSummary};
use crate::io::map_params::map_params_arg;
use crate::io::sequence::{read_gravity, sequence_frames, FrameSelection, SequenceFrame};
use crate::io::{self, CameraFile};
use crate::map::{GravitySource, GridMap, MapParams, MapSession, Pose, SessionFrame};
use crate::pipeline::{FrameInput, Mode, StageArgs};
use crate::record::msgs::{Header, Time};
use crate::record::{now_ns, Colour, FrameRecord, Recorder};
use crate::roughness::noise::SensorNoise;

/// Fuse a sequence of depth frames into a gravity-aligned roughness grid map.
#[derive(Debug, Args)]
pub(crate) struct Map {
    /// Sequence folder: `depth/*.png` (16-bit, the camera's depth_scale) or `depth/*.npy`,
    /// optional `poses/<stem>.txt` (4×4 camera-to-world, row by row) and `gravity.json`
    /// (`{"gravity": [x, y, z]}`, the world's down direction), and `intrinsics.json`.
    pub sequence: PathBuf,
    /// Camera JSON (default: the sequence's intrinsics.json).
    #[arg(long)]
    pub camera: Option<PathBuf>,
    /// Output folder: `<layer>.npy`, `<layer>.png`, `layers.png`, `map.json`.
    #[arg(long, short)]
    pub out: PathBuf,
    /// Map settings: a preset (`indoor`: 4 cm cells, an 8 m window, points to 4 m; `outdoor`:
    /// 10 cm cells, a 40 m window, points from 1 to 20 m) or a TOML settings file
    /// (docs/map.md).
    #[arg(long, default_value = "indoor")]
    pub params: String,
    /// Cell side, centimetres (default: the settings').
    #[arg(long)]
    pub cell_cm: Option<f64>,
    /// Side of the square map, metres (default: the settings').
    #[arg(long)]
    pub size_m: Option<f64>,
    /// What levels the map: `auto` (the sequence's gravity.json, else the camera's stated
    /// pitch, else the ground over the frames) or `ground` (the ground over the frames alone:
    /// every frame's confident ground fit turned into the world by its pose, averaged).
    #[arg(long, value_enum, default_value = "auto")]
    pub gravity: GravityChoice,
    /// Roughness from this mode (geometric: the spec on the depth; rgbd needs `rgb/<stem>.*`).
    #[arg(long, value_enum, default_value = "geometric")]
    pub mode: Mode,
    /// Depth sensor noise model (default: the camera's `sensor`): a preset or a,b,c.
    #[arg(long)]
    pub sensor: Option<SensorNoise>,
    /// Points farther than this from the camera are left out, metres (default: the
    /// settings'; the depth's noise grows with the square of the distance).
    #[arg(long)]
    pub max_range_m: Option<f64>,
    /// Record each frame's depth, pose and roughness and the final map to this MCAP file
    /// (ROS 2 messages and Foxglove schemas, docs/ros2.md); frames are stamped at 30 frames/s
    /// from the number their name ends with.
    #[arg(long)]
    pub record: Option<PathBuf>,
    /// Which frames, in which order.
    #[command(flatten)]
    pub select: FrameSelection,
    /// Pipeline switches and models (for the learned modes).
    #[command(flatten)]
    pub stages: StageArgs,
}

/// What levels the map.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub(crate) enum GravityChoice {
    /// gravity.json, else the stated pitch, else the ground.
    Auto,
    /// The ground over the frames alone.
    Ground,
}

impl Map {
    /// Fuses the sequence and writes the layers.
    pub(crate) fn run(self) -> anyhow::Result<()> {
        let params = self.params()?;
        let cam_path = self
            .camera
            .clone()
            .unwrap_or_else(|| self.sequence.join("intrinsics.json"));
        let (cam, k) = io::read_camera(&cam_path)?;
        let (sensor, scale) = self.sensor_and_scale(&cam)?;
        let frames = self.frames()?;
        let given = read_gravity(&self.sequence)?;
        let gravity = self.gravity_source(&cam, given)?;
        let mut session = MapSession::new(params, gravity, sensor);
        let pcfg = self.stages.config(self.mode);
        let mut pipeline = self.stages.pipeline(&[pcfg])?;
        let mut run = MapRun::default();
        let mut recorder = self.record.as_deref().map(create_recorder).transpose()?;
        for (i, f) in frames.iter().enumerate() {
            let depth_m = io::read_depth(&f.depth, scale)?;
            let pose = match frame_pose(f) {
                Ok(pose) => pose,
                Err(e) => {
                    run.skipped.push(format!("{}: {e:#}", f.stem));
                    continue;
                }
            };
            let points = k.back_project_map(&depth_m);
            let mut input = self.input(f, depth_m, k)?;
            input.sensor = Some(sensor);
            let out = pipeline.run(&input, &pcfg)?;
            if let Some(r) = &mut recorder {
                record_frame(r, f, i, &input, &pose, &out.roughness_m)?;
            }
            let frame = SessionFrame {
                points: &points,
                pose: Some(pose),
                t_s: i as f64,
                ground_up_in_cam: out.gravity.up_in_cam(),
            };
            pipeline.recycle(out);
            fuse_frame(&mut session, &frame, &f.stem, given, &mut run);
        }
        let map = session.map().context("no frame could start the map")?;
        let last = frames.len().checked_sub(1).map(|i| stamp(&frames[i], i));
        self.finish(
            map,
            session.params(),
            &run,
            recorder,
            last.unwrap_or_default(),
        )
    }

    /// What levels the map: `--gravity ground`, else the sequence's gravity.json, the camera's
    /// stated mounting or the ground, the first there is.
    fn gravity_source(
        &self,
        cam: &CameraFile,
        given: Option<Vec3>,
    ) -> anyhow::Result<GravitySource> {
        let up_in_cam = cam.mounting()?.map(|m| m.up_in_cam());
        Ok(match (self.gravity, given, up_in_cam) {
            (GravityChoice::Auto, Some(down), _) => GravitySource::Given(down),
            (GravityChoice::Auto, None, Some(up)) => GravitySource::Stated(up),
            _ => GravitySource::Ground,
        })
    }

    /// The settings: `--params`, changed by the flags given.
    fn params(&self) -> anyhow::Result<MapParams> {
        let p = map_params_arg(&self.params)?;
        Ok(p.with_flags(
            self.cell_cm.map(|cm| cm / 100.0),
            self.size_m,
            self.max_range_m,
        )?)
    }

    /// Records the map (stamped `last`, the last frame's stamp), writes its layers, and prints
    /// the summary and the frames skipped.
    fn finish(
        &self,
        map: &GridMap,
        params: &MapParams,
        run: &MapRun,
        recorder: Option<Recorder>,
        last: Time,
    ) -> anyhow::Result<()> {
        let layers = map.layers(&params.limits);
        let recorded = match recorder {
            Some(mut r) => {
                r.map(&Header::new(last, "map"), map, &layers, now_ns())?;
                Some(r.finish()?)
            }
            None => None,
        };
        let s = write_map(&self.out, map, &layers, run)?;
        print_summary(map, run, &s);
        if let Some(path) = recorded {
            println!("recorded {}", path.display());
        }
        for s in &run.skipped {
            eprintln!("skipped {s}");
        }
        Ok(())
    }

    /// The sequence's frames (stride, limit and order applied); without a pose for every
    /// frame, the first alone (a robot-centred map), with a warning.
    fn frames(&self) -> anyhow::Result<Vec<SequenceFrame>> {
        let mut frames = sequence_frames(&self.sequence, self.select)?;
        if !frames.iter().all(|f| f.pose.is_some()) {
            eprintln!("warning: no poses/ for every frame: one frame makes a robot-centred map");
            frames.truncate(1);
        }
        Ok(frames)
    }

    /// The noise model (`--sensor`, else the camera's) and the depth scale (the camera's): the
    /// map guesses neither.
    fn sensor_and_scale(&self, cam: &CameraFile) -> anyhow::Result<(SensorNoise, f64)> {
        let sensor = self
            .sensor
            .or_else(|| cam.sensor.as_ref().and_then(io::SensorSpec::noise))
            .context(
                "the map's height variance needs the depth sensor's noise model: give --sensor \
                 or a camera file with \"sensor\"",
            )?;
        let scale = cam.depth_scale.context(
            "the camera file states no depth_scale: the map will not guess the depth's units",
        )?;
        Ok((sensor, scale))
    }

    /// The pipeline's input for frame `f`: its depth, its colour when the mode reads it.
    fn input(
        &self,
        f: &SequenceFrame,
        depth_m: crate::geometry::Grid<f64>,
        k: crate::geometry::Intrinsics,
    ) -> anyhow::Result<FrameInput> {
        let rgb = match (&f.rgb, self.mode) {
            (Some(p), Mode::Rgb | Mode::Rgbd) => Some(io::read_image(p)?.to_rgb8()),
            _ => None,
        };
        Ok(FrameInput {
            rgb,
            depth_m: Some(depth_m),
            intrinsics: Some(k),
            mounting: None,
            sensor: None,
        })
    }
}

/// The run's summary line on stdout.
fn print_summary(map: &GridMap, run: &MapRun, s: &MapSummary) {
    let cfg = map.config();
    println!(
        "{} frames fused, {} skipped; {} cells seen: {:.1}% traversable, {:.1}% hazard, \
         {:.1}% unknown; fusion {:.1} ms a frame (median); map {} cells of {} cm, {:.1} MiB; \
         the sensor's height noise scaled by {:.2}",
        run.fused,
        run.skipped.len(),
        s.seen,
        100.0 * s.traversable,
        100.0 * s.hazard,
        100.0 * s.unknown,
        s.fuse_ms_median,
        cfg.side * cfg.side,
        100.0 * cfg.cell_m,
        map.memory_bytes() as f64 / f64::from(1 << 20),
        map.noise_scale().sqrt()
    );
}

/// A frame's stamp: the number its name ends with (else its place `i`) at 30 frames/s.
fn stamp(f: &SequenceFrame, i: usize) -> Time {
    let n = f.number().unwrap_or(i as u64) as i64;
    Time::from_nanos(n.saturating_mul(1_000_000_000) / 30)
}

/// A recorder writing `path`, its folder made first (as `-o` makes its own).
fn create_recorder(path: &std::path::Path) -> anyhow::Result<Recorder> {
    io::paths::create_parent(path)?;
    Ok(Recorder::create(path)?)
}

/// Records frame `f` (the `i`-th): its depth, colour, intrinsics and pose in, its roughness out.
fn record_frame(
    r: &mut Recorder,
    f: &SequenceFrame,
    i: usize,
    input: &FrameInput,
    pose: &Pose,
    roughness_m: &crate::geometry::Grid<f64>,
) -> anyhow::Result<()> {
    let record = FrameRecord {
        header: Header::new(stamp(f, i), "camera"),
        depth_m: input.depth_m.as_ref(),
        colour: input.rgb.as_ref().map(Colour::Raw),
        intrinsics: input.intrinsics.as_ref().map(|k| (k, roughness_m.size())),
        pose: Some((pose, "world")),
        roughness_m: Some(roughness_m),
        ..FrameRecord::default()
    };
    Ok(r.frame(&record, now_ns())?)
}

/// A frame's pose: its pose file read and checked rigid, the identity without one.
fn frame_pose(f: &SequenceFrame) -> anyhow::Result<Pose> {
    match f.pose.as_deref() {
        None => Ok(Pose::identity()),
        Some(path) => Ok(Pose::from_row_major(&io::read_pose(path)?)?),
    }
}

/// Fuses `frame` (of `stem`) into the session, and notes in `run` its time, whether it was
/// fused or why not, the camera's mark and how far the map's gravity is from `given`'s.
fn fuse_frame(
    session: &mut MapSession,
    frame: &SessionFrame<'_>,
    stem: &str,
    given: Option<Vec3>,
    run: &mut MapRun,
) {
    let start = Instant::now();
    let result = session.fuse(frame);
    run.fuse_ms.push(start.elapsed().as_secs_f64() * 1e3);
    let pose = frame.pose.unwrap_or_else(Pose::identity);
    if let (Ok(_), Some(m)) = (&result, session.map()) {
        run.trajectory.push(CameraMark::of(m, &pose));
    }
    match result {
        Ok(_) => run.fused += 1,
        Err(e) => run.skipped.push(format!("{stem}: {e}")),
    }
    run.gravity_deg
        .push(gravity_error_deg(session, &pose, given));
}

/// How far the session's gravity for the frame at `pose` is from the sequence's stated one
/// (`given`, the world's down), degrees: NaN when either is unknown.
fn gravity_error_deg(
    session: &MapSession,
    pose: &Pose,
    given: Option<crate::geometry::Vec3>,
) -> f64 {
    match (session.up_in_cam(pose), given) {
        (Some(up), Some(down)) => {
            let stated = -(pose.rotation.transpose() * down);
            up.angle(&stated).to_degrees()
        }
        _ => f64::NAN,
    }
}
