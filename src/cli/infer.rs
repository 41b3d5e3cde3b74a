//! `tre infer`: roughness for one frame through the pipeline, written as a 16-bit PNG (or float
//! `.npy`) with a colour preview beside it.

use std::path::{Path, PathBuf};

use anyhow::{bail, Context};
use clap::{Args, ValueEnum};
use image::DynamicImage;

use super::options::StageArgs;
use crate::io;
use crate::pipeline::{
    Assumption, FrameInput, FrameOutput, Method, Mode, PipelineConfig, PipelineError, SensorMaps,
    Traversability,
};
use crate::roughness::interval::IntervalTable;
use crate::roughness::noise::{SensorNoise, SensorPreset};
use crate::roughness::traversal::shares;

/// Output format of the roughness map.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum Format {
    /// 16-bit grey + alpha PNG, 0.1 mm per unit, alpha 0 where there is no data.
    Png16,
    /// (H, W) float32 .npy in metres, NaN where there is no data.
    Npy,
}

/// Estimate roughness for one frame.
#[derive(Debug, Args)]
pub struct Infer {
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
    #[arg(long, value_enum, default_value = "png16")]
    pub format: Format,
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
    /// realsense_d435, azure_kinect, lidar, exact) or coefficients a,b,c (σ_z = a + b·z + c·z²
    /// mm). With one (rgbd and geometric modes), the uncertainty map and the three-state map
    /// are written beside the output (docs/sensor-noise.md).
    #[arg(long, env = "TRE_SENSOR", value_parser = parse_sensor)]
    pub sensor: Option<SensorNoise>,
}

/// `--sensor`: a preset name or `a,b,c`.
pub(super) fn parse_sensor(s: &str) -> Result<SensorNoise, String> {
    s.parse()
}

impl Infer {
    /// Reads the frame, runs the pipeline and writes the roughness map and its preview.
    pub fn run(self) -> anyhow::Result<()> {
        self.check_outputs()?;
        if self.stages.method == Method::EndToEnd && self.depth.is_some() {
            bail!(
                "the end-to-end baseline runs from RGB alone, so --depth would be ignored: drop \
                 it, or use --method pipeline"
            );
        }
        let mode = self.mode()?;
        let traversability =
            Traversability::from_cm_deg(Some(self.max_roughness_cm), Some(self.max_slope_deg))
                .map_err(|e| anyhow::anyhow!("--{}", e.replace('_', "-")))?;
        let cfg = PipelineConfig {
            traversability,
            ..self.stages.config(mode)
        };
        let (frame, described, scale_stated) = self.read_frame()?;
        crate::pipeline::check_input(&frame, &cfg)?;
        let mut pipeline = self.stages.pipeline(&[cfg])?;
        let out = pipeline.run(&frame, &cfg)?;
        self.write(&out, &self.title("roughness", mode))?;
        let depth_png = self
            .depth
            .as_ref()
            .is_some_and(|d| !d.extension().is_some_and(|e| e.eq_ignore_ascii_case("npy")));
        let assumed = Assumption::of_frame(
            frame.intrinsics.is_some(),
            depth_png && !scale_stated,
            frame.mounting.is_some(),
            (mode, self.mode.is_some()),
        );
        for a in &assumed {
            eprintln!("warning: {a}");
        }
        print_summary(&out, &cfg);
        let table = pipeline.interval_table_for(&cfg);
        if let Some(maps) = self.sensor_maps(&out, &frame, &cfg, described, table)? {
            self.write_sensor_maps(&maps, &self.title("three-state", mode))?;
        }
        Ok(())
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
        let model = self
            .sensor
            .or(described.as_ref().and_then(io::SensorSpec::noise));
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
        print_shares(&what, &maps);
        Ok(Some(maps))
    }

    /// Writes `<stem>_uncertainty.png|npy`, the interval's ends `<stem>_lo.npy` and
    /// `<stem>_hi.npy` (`--format npy`, when calibrated), `<stem>_traversal.png` (0 unknown, 1 traversable,
    /// 2 hazard) and `<stem>_traversal_preview.png`.
    fn write_sensor_maps(&self, maps: &SensorMaps, title: &str) -> anyhow::Result<()> {
        let u = &maps.uncertainty_m;
        match self.format {
            Format::Png16 => io::save(
                &beside(&self.out, "uncertainty", "png"),
                &DynamicImage::ImageLumaA16(io::roughness_png16(u)),
            )?,
            Format::Npy => {
                io::write_npy_f32(&beside(&self.out, "uncertainty", "npy"), u)?;
                if let Some((lo, hi)) = &maps.interval_m {
                    io::write_npy_f32(&beside(&self.out, "lo", "npy"), lo)?;
                    io::write_npy_f32(&beside(&self.out, "hi", "npy"), hi)?;
                }
            }
        }
        let grey = io::traversal_gray8(&maps.traversal);
        io::save(
            &beside(&self.out, "traversal", "png"),
            &DynamicImage::ImageLuma8(grey),
        )?;
        let preview = io::colormap::traversal_preview(&maps.traversal, title);
        io::save(
            &beside(&self.out, "traversal_preview", "png"),
            &DynamicImage::ImageRgb8(preview),
        )?;
        Ok(())
    }

    /// Refuses, before any work, an output that could not hold the map or would replace an
    /// input, and a preview scale that is not a positive number.
    fn check_outputs(&self) -> anyhow::Result<()> {
        let ext = self
            .out
            .extension()
            .map(|e| e.to_string_lossy().to_ascii_lowercase());
        let wanted = match self.format {
            Format::Png16 => "png",
            Format::Npy => "npy",
        };
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
        let sensor_maps = [
            "uncertainty.png",
            "uncertainty.npy",
            "traversal.png",
            "traversal_preview.png",
        ]
        .map(|f| f.split_once('.').map(|(w, e)| beside(&self.out, w, e)));
        let mut outputs = vec![self.out.clone(), preview_path(&self.out)];
        outputs.extend(sensor_maps.into_iter().flatten());
        let outputs: Vec<&Path> = outputs.iter().map(PathBuf::as_path).collect();
        Ok(crate::io::paths::refuse_overwriting(&outputs, &inputs)?)
    }

    /// The mode asked for, or the one the inputs imply.
    fn mode(&self) -> anyhow::Result<Mode> {
        Ok(match (self.mode, &self.frame, &self.depth) {
            (Some(mode), _, _) => mode,
            (None, Some(_), Some(_)) => Mode::Rgbd,
            (None, None, Some(_)) => Mode::Geometric,
            (None, Some(_), None) => Mode::Rgb,
            (None, None, None) => bail!("give an RGB frame, --depth, or both"),
        })
    }

    /// The frame, depth and camera from disk, the camera's sensor, and whether a depth scale
    /// was given (`--depth-scale` or the camera's).
    fn read_frame(&self) -> anyhow::Result<(FrameInput, Option<io::SensorSpec>, bool)> {
        let cam = self.camera.as_deref().map(io::read_camera).transpose()?;
        let stated = self
            .depth_scale
            .or(cam.as_ref().and_then(|(c, _)| c.depth_scale));
        let scale = stated.unwrap_or(1000.0);
        if !(scale.is_finite() && scale > 0.0) {
            bail!("--depth-scale must be positive, got {scale}");
        }
        let rgb = match &self.frame {
            Some(path) => {
                let image = io::read_image(path)?;
                if let Some(why) = io::not_rgb(image.color()) {
                    bail!(
                        "{}: {why} (--depth, with --camera or --depth-scale)",
                        path.display()
                    );
                }
                Some(image.to_rgb8())
            }
            None => None,
        };
        let depth_m = match &self.depth {
            Some(path) => Some(io::read_depth(path, scale)?),
            None => None,
        };
        let mounting = match &cam {
            Some((c, _)) => c.mounting().context("camera pitch or height")?,
            None => None,
        };
        let frame = FrameInput {
            rgb,
            depth_m,
            intrinsics: cam.as_ref().map(|&(_, k)| k),
            mounting,
        };
        if let (Some((c, k)), Some(path), Some((w, h))) = (&cam, &self.camera, frame.size()) {
            let named = || format!("camera {}", path.display());
            c.check_size((w, h))
                .map_err(anyhow::Error::msg)
                .with_context(named)?;
            k.check_for(w, h).with_context(named)?;
        }
        Ok((frame, cam.and_then(|(c, _)| c.sensor), stated.is_some()))
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
        if let Some(dir) = self.out.parent().filter(|d| !d.as_os_str().is_empty()) {
            std::fs::create_dir_all(dir).with_context(|| format!("creating {}", dir.display()))?;
        }
        match self.format {
            Format::Png16 => io::save(
                &self.out,
                &DynamicImage::ImageLumaA16(io::roughness_png16(&out.roughness_m)),
            )?,
            Format::Npy => io::write_npy_f32(&self.out, &out.roughness_m)
                .with_context(|| format!("writing {}", self.out.display()))?,
        }
        let preview =
            io::colormap::roughness_preview(&out.roughness_m, self.preview_max_cm / 100.0, title);
        io::save(&preview_path(&self.out), &DynamicImage::ImageRgb8(preview))?;
        Ok(())
    }
}

/// `DIR/<stem>_<what>.<ext>` beside `out`.
fn beside(out: &Path, what: &str, ext: &str) -> PathBuf {
    let stem = out.file_stem().map_or_else(
        || "roughness".to_owned(),
        |s| s.to_string_lossy().into_owned(),
    );
    out.with_file_name(format!("{stem}_{what}.{ext}"))
}

/// `DIR/<stem>_preview.png` beside `out`.
fn preview_path(out: &Path) -> PathBuf {
    let stem = out.file_stem().map_or_else(
        || "roughness".to_owned(),
        |s| s.to_string_lossy().into_owned(),
    );
    out.with_file_name(format!("{stem}_preview.png"))
}

/// The results, gravity and timings, on stdout.
fn print_summary(out: &FrameOutput, cfg: &PipelineConfig) {
    let valid = crate::roughness::metrics::finite_sorted(&out.roughness_m);
    let median_cm = valid.get(valid.len() / 2).map_or(f64::NAN, |r| 100.0 * r);
    let (w, h) = out.working_size;
    let mode = if cfg.method == Method::EndToEnd {
        "the end-to-end baseline".to_owned()
    } else {
        format!("mode {}", cfg.mode)
    };
    println!(
        "{mode} ({}) at {w}×{h}: {} px with roughness, median {median_cm:.3} cm",
        stage_names(cfg),
        valid.len()
    );
    println!("gravity: {}", out.gravity);
    let slope_limit = cfg.traversability.max_slope_rad.to_degrees();
    let rough_limit = 100.0 * cfg.traversability.max_roughness_m;
    let ok = out.traversable().as_slice().iter().filter(|&&t| t).count();
    if out.slope_rad().is_none() {
        println!("binary map: {ok} px with roughness < {rough_limit} cm (no normals, so no slope)");
    } else if out.gravity.up_in_cam().is_none() {
        println!("binary map: none traversable: gravity unknown, so no slope < {slope_limit}° can be shown");
    } else {
        println!(
            "binary map: {ok} px with roughness < {rough_limit} cm and slope < {slope_limit}°"
        );
    }
    let stages: Vec<String> = out
        .timings
        .iter()
        .map(|(name, d)| format!("{name} {:.1}", d.as_secs_f64() * 1e3))
        .collect();
    println!("ms: {}", stages.join(", "));
}

/// The stages in words: the pipeline label's abbreviations spelt out.
fn stage_names(cfg: &PipelineConfig) -> String {
    cfg.label()
        .split('+')
        .map(|p| match p {
            "DE" => "depth net".to_owned(),
            "LS" => "least-squares normals".to_owned(),
            "NR" => "normal refiner".to_owned(),
            "ESR" => "centroid net".to_owned(),
            "window" => "window centroids".to_owned(),
            "edge" => "edge term".to_owned(),
            "E2E" => "end-to-end net".to_owned(),
            d if d.starts_with("DSAC") => format!("DSAC normals ({d})"),
            other => other.to_owned(),
        })
        .collect::<Vec<_>>()
        .join(" + ")
}

/// Prints the three states' shares of `maps`, naming where they come from.
fn print_shares(what: &str, maps: &SensorMaps) {
    let (t, h, u) = shares(&maps.traversal);
    println!(
        "{what}: {:.1}% traversable, {:.1}% hazard, {:.1}% unknown",
        100.0 * t,
        100.0 * h,
        100.0 * u
    );
}
