//! `tre infer`: roughness for one frame through the pipeline, written as a 16-bit PNG (or float
//! `.npy`) with a colour preview beside it.

mod record;

use std::path::{Path, PathBuf};

use anyhow::{bail, Context};
use clap::Args;

use crate::io;
use crate::io::outputs::{self, SensorMapFiles};
use crate::kinds::{value_parser_of, MapFormat};
use crate::pipeline::{
    Assumption, FrameInput, FrameOutput, Method, Mode, PipelineConfig, PipelineError, SensorMaps,
    StageArgs, Traversability,
};
use crate::roughness::interval::IntervalTable;
use crate::roughness::noise::{SensorNoise, SensorPreset};

/// Estimate roughness for one frame.
#[derive(Debug, Args)]
pub(crate) struct Infer {
    /// RGB frame (PNG or JPEG); not needed in geometric mode.
    pub frame: Option<PathBuf>,
    /// Registered depth of the same size: 16-bit grey PNG (see --depth-scale) or float .npy in
    /// metres; 0 = no data.
    #[arg(long)]
    pub depth: Option<PathBuf>,
    /// Depth PNG units per metre (1000: millimetres); default: the camera JSON's depth_scale,
    /// else 1000.
    #[arg(long, env = "TRE_DEPTH_SCALE")]
    pub depth_scale: Option<f64>,
    /// Camera JSON (cameras/README.md): fx, fy, cx, cy in pixels of this frame; optional
    /// depth_scale, sensor, pitch_deg and height_m; metadata under "notes". Without it: a 60°
    /// horizontal field of view, centred (a warning says so). Without pitch_deg, gravity comes
    /// from the depth's ground plane, else it is unknown.
    #[arg(long)]
    pub camera: Option<PathBuf>,
    /// Input mode; default: rgbd with a frame and --depth, geometric with --depth alone, else
    /// rgb.
    #[arg(long, value_enum)]
    pub mode: Option<Mode>,
    /// Pipeline switches and models.
    #[command(flatten)]
    pub stages: StageArgs,
    /// Output roughness file; the preview goes beside it as `<stem>_preview.png`.
    #[arg(long, short)]
    pub out: PathBuf,
    /// Output format.
    #[arg(long, default_value = "png16", value_parser = value_parser_of(MapFormat::FILE))]
    pub format: MapFormat,
    /// Top of the preview's colour scale, centimetres.
    #[arg(long, default_value_t = 5.0)]
    pub preview_max_cm: f64,
    /// Traversability (the summary's count): the largest roughness, centimetres.
    #[arg(long, default_value_t = 5.0)]
    pub max_roughness_cm: f64,
    /// Traversability: the steepest slope, degrees.
    #[arg(long, default_value_t = 20.0)]
    pub max_slope_deg: f64,
    /// Depth sensor noise model, overriding the camera JSON's "sensor": a preset (kinect_v1,
    /// realsense_d435, azure_kinect, lidar, lidar_accumulated, passive_stereo, exact) or
    /// coefficients a,b,c (σ_z = a + b·z + c·z² mm). With one (rgbd and geometric modes), the uncertainty map and the three-state map
    /// are written beside the output (docs/sensor-noise.md).
    #[arg(long, env = "TRE_SENSOR")]
    pub sensor: Option<SensorNoise>,
}

/// What one frame gave: the output, the maps beside it and what was said about them.
struct Done {
    /// The pipeline's output.
    out: FrameOutput,
    /// The uncertainty and three-state maps, where the frame has them.
    maps: Option<SensorMaps>,
    /// What stood in for what was not given.
    assumed: Vec<Assumption>,
    /// The other warnings, in words (an implausible depth, a map mostly unknown).
    warnings: Vec<String>,
}

impl Infer {
    /// Reads the frame, runs the pipeline and writes the roughness map, its preview, the
    /// sensor maps where there are some, and the run's JSON record ([`record`]).
    pub(crate) fn run(self) -> anyhow::Result<()> {
        self.check_outputs()?;
        let cfg = self.config()?;
        let mode = cfg.mode;
        let (mut frame, described, (scale_stated, scale)) = self.read_frame()?;
        frame.sensor = self
            .sensor
            .or(described.as_ref().and_then(io::SensorSpec::noise));
        crate::pipeline::check_input(&frame, &cfg)?;
        let mut pipeline = self.stages.pipeline(&[cfg])?;
        let out = pipeline.run(&frame, &cfg)?;
        let assumed = Assumption::of_frame(
            frame.intrinsics.is_some(),
            self.depth_png() && !scale_stated,
            (frame.mounting.is_some(), frame.sensor.is_some()),
            (mode, self.mode.is_some()),
        );
        for a in &assumed {
            eprintln!("warning: {a}");
        }
        let mut warnings: Vec<String> = out.implausible.iter().map(|b| b.message(scale)).collect();
        warnings.iter().for_each(|w| eprintln!("warning: {w}"));
        out.summary(&cfg).iter().for_each(|l| println!("{l}"));
        let table = pipeline.interval_table_for(&cfg);
        let text = match &described {
            Some(io::SensorSpec::Description(d)) => Some(d.clone()),
            _ => None,
        };
        let maps = self.sensor_maps(&out, &frame, &cfg, described, table)?;
        if let Some(caveat) = maps.as_ref().and_then(SensorMaps::mostly_unknown) {
            let words = format!("the three-state map is {caveat}");
            eprintln!("warning: {words}");
            warnings.push(words);
        }
        let done = Done {
            out,
            maps,
            assumed,
            warnings,
        };
        let files = self.write_all(&done, mode)?;
        self.write_record(&record::Run {
            inputs: [&self.frame, &self.depth, &self.camera].map(|p| p.as_deref()),
            cfg: (&cfg, self.mode.is_some()),
            out: &done.out,
            said: (&done.assumed, &done.warnings),
            sensor: (frame.sensor.map(|s| s.label()), text.as_deref()),
            depth_scale: self.depth_png().then_some((scale, scale_stated)),
            models: pipeline.models().map(crate::model::Models::manifest),
            maps: done.maps.as_ref(),
            files: &files,
        })
    }

    /// The configuration to run: the mode asked for or implied, the stages, the
    /// traversability thresholds; depth that the mode or method would drop is refused.
    fn config(&self) -> anyhow::Result<PipelineConfig> {
        if self.stages.config.method == Method::EndToEnd && self.depth.is_some() {
            bail!(
                "the end-to-end baseline runs from RGB alone, so --depth would be ignored: drop \
                 it, or use --method pipeline"
            );
        }
        let mode = self.mode()?;
        let traversability =
            Traversability::from_cm_deg(Some(self.max_roughness_cm), Some(self.max_slope_deg))
                .map_err(|e| anyhow::anyhow!("--{}", e.to_string().replace('_', "-")))?;
        let cfg = PipelineConfig {
            traversability,
            ..self.stages.config(mode)
        };
        cfg.check_depth_used(self.depth.is_some())
            .context("--mode rgb with --depth")?;
        Ok(cfg)
    }

    /// Writes the run's record beside the map ([`record::record_path`]).
    fn write_record(&self, run: &record::Run<'_>) -> anyhow::Result<()> {
        let json = serde_json::to_string_pretty(&record::record(run))?;
        io::paths::write_text(&record::record_path(&self.out), &(json + "\n"))?;
        Ok(())
    }

    /// Whether the depth is a PNG (read at a depth scale) rather than an `.npy` in metres.
    fn depth_png(&self) -> bool {
        self.depth
            .as_ref()
            .is_some_and(|d| !d.extension().is_some_and(|e| e.eq_ignore_ascii_case("npy")))
    }

    /// Writes the roughness map and its preview, and the sensor maps where there are some, each
    /// preview titled with the mode and the input and, for a map mostly unknown, saying so.
    /// Returns the files written, each preview with its title.
    fn write_all(&self, done: &Done, mode: Mode) -> anyhow::Result<Vec<(PathBuf, Option<String>)>> {
        let caveat = done.maps.as_ref().and_then(SensorMaps::mostly_unknown);
        let title = |what| {
            let t = self.title(what, mode);
            caveat
                .as_ref()
                .map_or(t.clone(), |c| format!("{t} - {}", c.to_uppercase()))
        };
        let rough_title = title("roughness");
        self.write(&done.out, &rough_title)?;
        let mut files = vec![
            (self.out.clone(), None),
            (outputs::preview_path(&self.out), Some(rough_title)),
        ];
        if let Some(maps) = &done.maps {
            let map_title = title("three-state");
            self.write_sensor_maps(maps, &map_title)?;
            let ext = self.format.extension();
            files.push((outputs::beside(&self.out, "uncertainty", ext), None));
            if let ("npy", Some(_)) = (ext, &maps.interval_m) {
                files.push((outputs::beside(&self.out, "lo", "npy"), None));
                files.push((outputs::beside(&self.out, "hi", "npy"), None));
            }
            files.push((outputs::beside(&self.out, "traversal", "png"), None));
            let preview = outputs::beside(&self.out, "traversal_preview", "png");
            files.push((preview, Some(map_title)));
        }
        Ok(files)
    }

    /// The uncertainty and three-state maps by the service's rule
    /// ([`FrameOutput::sensor_maps`]): the noise model is `--sensor`, else the camera's `sensor`
    /// (`described`: the camera's sensor, a model or free text); `rgb` reads the mode's
    /// calibration `table` alone. Where the rule finds no sensor depth or no noise model, a
    /// note on stderr; `--sensor` in a mode without sensor depth is an error.
    fn sensor_maps(
        &self,
        out: &FrameOutput,
        frame: &FrameInput,
        cfg: &PipelineConfig,
        described: Option<io::SensorSpec>,
        table: Option<&IntervalTable>,
    ) -> anyhow::Result<Option<SensorMaps>> {
        if self.sensor.is_some() && cfg.mode == Mode::Rgb {
            bail!("--sensor: the rgb mode reads no sensor depth; its intervals come from models/uncertainty.json");
        }
        // The input's model: `--sensor`, else the camera's (set in `run`).
        let model = frame.sensor;
        let text = match &described {
            Some(io::SensorSpec::Description(d)) => Some(d.as_str()),
            _ => None,
        };
        let maps = match out.sensor_maps(frame, cfg.mode, model.as_ref(), text, table) {
            Ok(maps) => maps,
            Err(e) if self.sensor.is_some() => return Err(e).context("--sensor"),
            Err(PipelineError::NoSensorModel { .. }) => {
                if let Some(d) = text {
                    eprintln!(
                        "note: the camera's sensor {d:?} names no noise model, so no uncertainty or \
                         three-state map is written; give --sensor (one of {}) or a,b,c",
                        SensorPreset::names()
                    );
                }
                return Ok(None);
            }
            Err(PipelineError::NoSensorDepth { .. }) => {
                if model.is_some() {
                    eprintln!(
                        "note: no uncertainty or three-state map in {} (no sensor depth)",
                        cfg.label()
                    );
                }
                return Ok(None);
            }
            Err(e) => return Err(e.into()),
        };
        let what = match (model.filter(|_| cfg.mode != Mode::Rgb), table) {
            (Some(m), Some(_)) => format!("sensor {} with calibrated intervals", m.label()),
            (Some(m), None) => format!("sensor {}", m.label()),
            (None, _) => "calibrated intervals".to_owned(),
        };
        println!("{}", maps.shares_line(&what));
        Ok(Some(maps))
    }

    /// Writes the uncertainty and three-state maps beside the output
    /// ([`outputs::write_sensor_maps`]).
    fn write_sensor_maps(&self, maps: &SensorMaps, title: &str) -> anyhow::Result<()> {
        let files = SensorMapFiles {
            uncertainty_m: &maps.uncertainty_m,
            interval_m: maps.interval_m.as_ref().map(|(lo, hi)| (lo, hi)),
            traversal: &maps.traversal,
        };
        let max_m = self.preview_max_cm / 100.0;
        Ok(outputs::write_sensor_maps(
            &self.out,
            self.format,
            &files,
            max_m,
            title,
        )?)
    }

    /// Refuses, before any work, an output that could not hold the map or would replace an
    /// input, and a preview scale that is not a positive number.
    fn check_outputs(&self) -> anyhow::Result<()> {
        let ext = self
            .out
            .extension()
            .map(|e| e.to_string_lossy().to_ascii_lowercase());
        let wanted = self.format.extension();
        if ext.as_deref() != Some(wanted) {
            bail!(
                "-o {}: the {} format writes a .{wanted} file; name it so (other image kinds \
                 cannot hold the 16-bit map)",
                self.out.display(),
                wanted
            );
        }
        if !(self.preview_max_cm.is_finite() && self.preview_max_cm > 0.0) {
            bail!(
                "--preview-max-cm must be a positive number, got {}",
                self.preview_max_cm
            );
        }
        let inputs: Vec<&Path> = [&self.frame, &self.depth, &self.camera]
            .into_iter()
            .flatten()
            .map(PathBuf::as_path)
            .collect();
        let mut outputs = vec![self.out.clone(), outputs::preview_path(&self.out)];
        outputs.extend(outputs::sensor_map_paths(&self.out));
        outputs.push(record::record_path(&self.out));
        let outputs: Vec<&Path> = outputs.iter().map(PathBuf::as_path).collect();
        Ok(crate::io::paths::refuse_overwriting(&outputs, &inputs)?)
    }

    /// The mode asked for, or the one the inputs imply.
    fn mode(&self) -> anyhow::Result<Mode> {
        match (self.mode, self.frame.is_some(), self.depth.is_some()) {
            (Some(mode), _, _) => Ok(mode),
            (None, false, false) => bail!("give an RGB frame, --depth, or both"),
            (None, rgb, depth) => Ok(Mode::implied(rgb, depth)),
        }
    }

    /// The frame, depth and camera from disk ([`io::read_frame_files`]), the camera's sensor,
    /// and whether a depth scale was given (`--depth-scale` or the camera's).
    fn read_frame(&self) -> anyhow::Result<(FrameInput, Option<io::SensorSpec>, (bool, f64))> {
        let read = io::read_frame_files(&io::FrameFiles {
            rgb: self.frame.as_deref(),
            depth: self.depth.as_deref(),
            camera: self.camera.as_deref(),
            depth_scale: self.depth_scale,
        })?;
        let frame = FrameInput {
            rgb: read.rgb,
            depth_m: read.depth_m,
            intrinsics: read.camera.as_ref().map(|&(_, k)| k),
            mounting: read.mounting,
            sensor: None,
        };
        let sensor = read.camera.and_then(|(c, _)| c.sensor);
        Ok((frame, sensor, (read.scale_stated, read.scale)))
    }

    /// A preview's title: `what`, the mode and the input's file name.
    fn title(&self, what: &str, mode: Mode) -> String {
        let input = self.frame.as_ref().or(self.depth.as_ref());
        let name = input.map_or_else(String::new, |p| super::annotate::file_name(p));
        format!("{what}, mode {mode}: {name}")
    }

    /// Writes the roughness map in the chosen format and the preview (titled `title`) beside
    /// it.
    fn write(&self, out: &FrameOutput, title: &str) -> anyhow::Result<()> {
        let max_m = self.preview_max_cm / 100.0;
        outputs::write_roughness(&self.out, self.format, &out.roughness_m, max_m, title)
            .with_context(|| format!("writing {}", self.out.display()))
    }
}
