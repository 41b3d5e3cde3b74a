//! `tre map`: a sequence of depth frames (with their poses) fused into the robot's grid map,
//! written layer by layer (docs/map.md).

use std::path::{Path, PathBuf};
use std::time::Instant;

use anyhow::{bail, Context};
use clap::Args;
use image::{DynamicImage, Rgb, RgbImage};
use serde_json::json;

use super::infer::parse_sensor;
use super::options::StageArgs;
use crate::geometry::floor::{fit_floor, FloorFitConfig};
use crate::geometry::{Grid, Vec3};
use crate::io::{self, sheet};
use crate::map::{GridMap, Layers, MapConfig, MapFrame, MapLimits, Pose, LAYER_NAMES};
use crate::pipeline::{FrameInput, Mode};
use crate::roughness::noise::SensorNoise;

/// Fuse a sequence of depth frames into a gravity-aligned roughness grid map.
#[derive(Debug, Args)]
pub struct Map {
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
    /// Cell side, centimetres.
    #[arg(long, default_value_t = 4.0)]
    pub cell_cm: f64,
    /// Side of the square map, metres.
    #[arg(long, default_value_t = 8.0)]
    pub size_m: f64,
    /// Roughness from this mode (geometric: the spec on the depth; rgbd needs `rgb/<stem>.*`).
    #[arg(long, value_enum, default_value = "geometric")]
    pub mode: Mode,
    /// Depth sensor noise model (default: the camera's `sensor`): a preset or a,b,c.
    #[arg(long, value_parser = parse_sensor)]
    pub sensor: Option<SensorNoise>,
    /// Points farther than this from the camera are left out, metres (the depth's noise
    /// grows with the square of the distance).
    #[arg(long, default_value_t = 3.0)]
    pub max_range_m: f64,
    /// Use every Nth frame.
    #[arg(long, default_value_t = 1)]
    pub stride: usize,
    /// Use at most this many frames.
    #[arg(long)]
    pub limit: Option<usize>,
    /// Fuse the frames in reverse order (the map should not depend on the order).
    #[arg(long)]
    pub reverse: bool,
    /// Pipeline switches and models (for the learned modes).
    #[command(flatten)]
    pub stages: StageArgs,
}

/// One frame of a sequence.
struct SeqFrame {
    stem: String,
    depth: PathBuf,
    rgb: Option<PathBuf>,
    pose: Option<PathBuf>,
}

impl Map {
    /// Fuses the sequence and writes the layers.
    pub fn run(self) -> anyhow::Result<()> {
        let cam_path = self
            .camera
            .clone()
            .unwrap_or_else(|| self.sequence.join("intrinsics.json"));
        let (cam, k) = io::read_camera(&cam_path)?;
        let (sensor, scale) = self.sensor_and_scale(&cam)?;
        let mut frames = self.frames()?;
        let posed = frames.iter().all(|f| f.pose.is_some());
        if !posed {
            eprintln!("warning: no poses/ for every frame: one frame makes a robot-centred map");
            frames.truncate(1);
        }
        let cfg = MapConfig {
            cell_m: self.cell_cm / 100.0,
            side: (self.size_m / (self.cell_cm / 100.0)).round() as usize,
            max_range_m: self.max_range_m,
            ..MapConfig::default()
        };
        let pcfg = self.stages.config(self.mode);
        let mut pipeline = self.stages.pipeline(&[pcfg])?;
        let mut map: Option<GridMap> = None;
        let (mut fused, mut skipped, mut fuse_ms) = (0usize, Vec::new(), Vec::new());
        for (i, f) in frames.iter().enumerate() {
            let depth_m = io::read_depth(&f.depth, scale)?;
            let pose = match &f.pose {
                Some(p) => match read_pose(p) {
                    Ok(pose) => pose,
                    Err(e) => {
                        skipped.push(format!("{}: {e:#}", f.stem));
                        continue;
                    }
                },
                None => Pose::identity(),
            };
            let points = k.back_project_map(&depth_m);
            let m = match &mut map {
                Some(m) => m,
                None => {
                    let frame = self.map_frame(&points, &pose, cam.mounting()?)?;
                    let c = frame.map_from_world * pose.translation;
                    map.insert(GridMap::new(cfg, frame, (c.x, c.y))?)
                }
            };
            let input = self.input(f, depth_m, k)?;
            let out = pipeline.run(&input, &pcfg)?;
            let start = Instant::now();
            let result = m.fuse(&points, Some(&out.roughness_m), &pose, i as f64, |z| {
                sensor.sigma_z_m(z)
            });
            fuse_ms.push(start.elapsed().as_secs_f64() * 1e3);
            pipeline.recycle(out);
            match result {
                Ok(_) => fused += 1,
                Err(e) => skipped.push(format!("{}: {e}", f.stem)),
            }
        }
        let map = map.context("no frame could start the map")?;
        let layers = map.layers(&MapLimits::default());
        self.write(&map, &layers, (fused, &skipped, &mut fuse_ms))
    }

    /// The noise model (`--sensor`, else the camera's) and the depth scale (the camera's): the
    /// map guesses neither.
    fn sensor_and_scale(&self, cam: &io::CameraFile) -> anyhow::Result<(SensorNoise, f64)> {
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
        f: &SeqFrame,
        depth_m: Grid<f64>,
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
        })
    }

    /// The map frame: `gravity.json` beside the sequence, else the stated pitch, else the
    /// first frame's ground plane (turned into the world by its pose).
    fn map_frame(
        &self,
        points: &crate::geometry::PointMap,
        pose: &Pose,
        mounting: Option<crate::geometry::Mounting>,
    ) -> anyhow::Result<MapFrame> {
        let g = self.sequence.join("gravity.json");
        if g.is_file() {
            let v: serde_json::Value = serde_json::from_slice(&std::fs::read(&g)?)
                .with_context(|| format!("reading {}", g.display()))?;
            let d: Vec<f64> = serde_json::from_value(v["gravity"].clone())
                .with_context(|| format!("{}: expected {{\"gravity\": [x, y, z]}}", g.display()))?;
            if d.len() != 3 {
                bail!("{}: gravity must have 3 components", g.display());
            }
            return Ok(MapFrame::from_gravity(&Vec3::new(d[0], d[1], d[2]))?);
        }
        let up_cam = match mounting {
            Some(m) => m.up_in_cam(),
            None => {
                let fit = fit_floor(points, &FloorFitConfig::default())
                    .context("no gravity.json, no pitch_deg, and no ground in the first frame")?;
                if !fit.confident {
                    bail!(
                        "no gravity.json, no pitch_deg, and the first frame's ground fit is not \
                         confident ({:.1}% on it): the map cannot be levelled",
                        100.0 * fit.support
                    );
                }
                fit.up_in_cam
            }
        };
        Ok(MapFrame::from_gravity(&-(pose.rotation * up_cam))?)
    }

    /// The sequence's frames in order (stride, limit, reverse applied).
    fn frames(&self) -> anyhow::Result<Vec<SeqFrame>> {
        let dir = self.sequence.join("depth");
        let mut depths: Vec<PathBuf> = std::fs::read_dir(&dir)
            .with_context(|| format!("reading {}", dir.display()))?
            .filter_map(Result::ok)
            .map(|e| e.path())
            .filter(|p| p.extension().is_some_and(|e| e == "png" || e == "npy"))
            .collect();
        depths.sort();
        if depths.is_empty() {
            bail!("{}: no .png or .npy depth frame", dir.display());
        }
        let mut frames: Vec<SeqFrame> = depths
            .into_iter()
            .step_by(self.stride.max(1))
            .map(|depth| {
                let stem = depth
                    .file_stem()
                    .map(|s| s.to_string_lossy().into_owned())
                    .unwrap_or_default();
                let pose = Some(self.sequence.join("poses").join(format!("{stem}.txt")))
                    .filter(|p| p.is_file());
                let rgb = ["jpg", "png"]
                    .iter()
                    .map(|e| self.sequence.join("rgb").join(format!("{stem}.{e}")))
                    .find(|p| p.is_file());
                SeqFrame {
                    stem,
                    depth,
                    rgb,
                    pose,
                }
            })
            .collect();
        if let Some(n) = self.limit {
            frames.truncate(n);
        }
        if self.reverse {
            frames.reverse();
        }
        Ok(frames)
    }

    /// Writes every layer (`.npy` float32 and 16-bit `.png`), `layers.png` and `map.json`,
    /// and prints the summary.
    fn write(
        &self,
        map: &GridMap,
        layers: &Layers,
        (fused, skipped, fuse_ms): (usize, &[String], &mut Vec<f64>),
    ) -> anyhow::Result<()> {
        std::fs::create_dir_all(&self.out)
            .with_context(|| format!("creating {}", self.out.display()))?;
        let mut meta = serde_json::Map::new();
        for (name, grid) in LAYER_NAMES.iter().zip(layers.all()) {
            meta.insert((*name).to_owned(), self.write_layer(name, grid)?);
        }
        io::save(
            &self.out.join("layers.png"),
            &DynamicImage::ImageRgb8(picture(layers)),
        )?;
        let cfg = map.config();
        let (tr, hz, un, seen) = shares(&layers.traversal, &layers.count);
        fuse_ms.sort_by(f64::total_cmp);
        let median_ms = fuse_ms.get(fuse_ms.len() / 2).copied().unwrap_or(f64::NAN);
        let geometry = json!({
            "cell_m": cfg.cell_m,
            "side_cells": cfg.side,
            "origin_cell": [map.origin().0, map.origin().1],
            "centre_m": [map.centre().0, map.centre().1],
            "map_from_world": map.frame().map_from_world.transpose().as_slice(),
            "layout": "row-major (side, side) float32; column 0 at the smallest x, row 0 at the largest y; the cell of column c, row r spans x in [(origin_x + c)·cell, +cell), y in [(origin_y + side − 1 − r)·cell, +cell) of the map frame (z up)",
            "png": "16-bit grey: 0 = no data, else value = png_offset + (png − 1)·png_scale",
            "layers": meta,
            "frames_fused": fused,
            "frames_skipped": skipped,
            "memory_bytes": map.memory_bytes(),
            "fuse_ms_median": median_ms,
        });
        std::fs::write(
            self.out.join("map.json"),
            serde_json::to_string_pretty(&geometry)?,
        )?;
        println!(
            "{fused} frames fused, {} skipped; {seen} cells seen: {:.1}% traversable, {:.1}% hazard, \
             {:.1}% unknown; fusion {median_ms:.1} ms a frame (median); map {} cells of {} cm, {:.1} MiB",
            skipped.len(),
            100.0 * tr,
            100.0 * hz,
            100.0 * un,
            cfg.side * cfg.side,
            100.0 * cfg.cell_m,
            map.memory_bytes() as f64 / f64::from(1 << 20)
        );
        for s in skipped {
            eprintln!("skipped {s}");
        }
        Ok(())
    }
}

impl Map {
    /// Writes layer `name` as `<name>.npy` (float32) and `<name>.png` (16-bit, 0 = no data);
    /// its unit and PNG scale for `map.json`.
    fn write_layer(&self, name: &str, grid: &Grid<f32>) -> anyhow::Result<serde_json::Value> {
        let g64 = grid.map(|&v| f64::from(v));
        io::write_npy_f32(&self.out.join(format!("{name}.npy")), &g64)?;
        let (scale, offset, unit) = png_scale(name, &g64);
        let png = Grid::from_fn(g64.width(), g64.height(), |x, y| {
            let v = g64[(x, y)];
            if v.is_finite() {
                (1.0 + ((v - offset) / scale).round()).clamp(1.0, 65535.0) as u16
            } else {
                0
            }
        });
        let img = image::ImageBuffer::<image::Luma<u16>, Vec<u16>>::from_raw(
            png.width() as u32,
            png.height() as u32,
            png.into_vec(),
        )
        .context("layer image")?;
        io::save(
            &self.out.join(format!("{name}.png")),
            &DynamicImage::ImageLuma16(img),
        )?;
        Ok(json!({"unit": unit, "png_scale": scale, "png_offset": offset}))
    }
}

/// Scale, offset and unit of a layer's 16-bit PNG.
fn png_scale(name: &str, g: &Grid<f64>) -> (f64, f64, &'static str) {
    let min = g
        .as_slice()
        .iter()
        .copied()
        .filter(|v| v.is_finite())
        .fold(f64::INFINITY, f64::min);
    let min = if min.is_finite() { min } else { 0.0 };
    match name {
        "elevation" => (0.0005, (min * 100.0).floor() / 100.0, "m"),
        "variance" => (1e-8, 0.0, "m^2"),
        "count" => (1.0, 0.0, "measurements"),
        "roughness" | "step" => (0.0001, 0.0, "m"),
        "slope" => (0.01, 0.0, "degrees"),
        "score" => (1.0 / 10000.0, 0.0, "0 to 1"),
        "traversal" => (1.0, 0.0, "0 unknown, 1 traversable, 2 hazard"),
        _ => (0.01, (min * 100.0).floor() / 100.0, "s"),
    }
}

/// Shares of traversable, hazard and unknown among the seen cells, and the seen cells.
fn shares(traversal: &Grid<f32>, count: &Grid<f32>) -> (f64, f64, f64, usize) {
    let seen: Vec<f32> = traversal
        .as_slice()
        .iter()
        .zip(count.as_slice())
        .filter(|(_, &c)| c > 0.0)
        .map(|(&t, _)| t)
        .collect();
    let n = seen.len().max(1) as f64;
    let share = |s: f32| seen.iter().filter(|&&t| t == s).count() as f64 / n;
    (share(1.0), share(2.0), share(0.0), seen.len())
}

/// The layers side by side: elevation, roughness, slope, step, score, three-state.
fn picture(l: &Layers) -> RgbImage {
    let scaled = |g: &Grid<f32>, lo: f64, hi: f64| {
        io::colormap::colourise(&g.map(|&v| f64::from(v)), lo, hi)
    };
    let finite = |g: &Grid<f32>| -> (f64, f64) {
        let v: Vec<f64> = g
            .as_slice()
            .iter()
            .filter(|v| v.is_finite())
            .map(|&v| f64::from(v))
            .collect();
        let lo = v.iter().copied().fold(f64::INFINITY, f64::min);
        let hi = v.iter().copied().fold(f64::NEG_INFINITY, f64::max);
        if lo.is_finite() {
            (lo, hi.max(lo + 1e-3))
        } else {
            (0.0, 1.0)
        }
    };
    let (elo, ehi) = finite(&l.elevation);
    let trav = traversal_image(l);
    let panels = [
        sheet::Panel::new(
            format!("elevation {elo:.2}..{ehi:.2} m"),
            scaled(&l.elevation, elo, ehi),
        ),
        sheet::Panel::new("roughness 0..5 cm", scaled(&l.roughness, 0.0, 0.05)),
        sheet::Panel::new("slope 0..30 deg", scaled(&l.slope, 0.0, 30.0)),
        sheet::Panel::new("step 0..10 cm", scaled(&l.step, 0.0, 0.10)),
        sheet::Panel::new("score 0..1", scaled(&l.score, 0.0, 1.0)),
        sheet::Panel::new("three-state", trav),
    ];
    let legend = map_legend();
    sheet::contact_sheet(&panels, 3, Some(&legend))
}

/// The three-state layer in the previews' colours, never-seen cells dark.
fn traversal_image(l: &Layers) -> RgbImage {
    use crate::roughness::traversal::Traversal;
    let (w, h) = l.traversal.size();
    RgbImage::from_fn(w as u32, h as u32, |x, y| {
        let (x, y) = (x as usize, y as usize);
        if l.count[(x, y)] == 0.0 {
            return Rgb(NOT_SEEN);
        }
        Rgb(io::colormap::traversal_rgb(
            match l.traversal[(x, y)] as u8 {
                1 => Traversal::Traversable,
                2 => Traversal::Hazard,
                _ => Traversal::Unknown,
            },
        ))
    })
}

/// Colour of cells never seen.
const NOT_SEEN: [u8; 3] = [40, 40, 40];

/// The legend of the three-state panel.
fn map_legend() -> RgbImage {
    use crate::roughness::traversal::Traversal;
    let c = |t| Rgb(io::colormap::traversal_rgb(t));
    sheet::categorical_legend(&[
        ("traversable", c(Traversal::Traversable)),
        ("hazard", c(Traversal::Hazard)),
        ("unknown", c(Traversal::Unknown)),
        ("not seen", Rgb(NOT_SEEN)),
    ])
}

/// A 4×4 camera-to-world pose from a text file of 16 numbers, checked rigid.
fn read_pose(path: &Path) -> anyhow::Result<Pose> {
    Ok(Pose::from_row_major(&io::read_pose(path)?)?)
}
