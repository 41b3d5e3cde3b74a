//! Truth that is not the same raw depth: known-flat and known-hazard regions picked by eye on
//! the real frames (`tests/fixtures/real_regions.json`, its `rule` says how), scored per
//! sensor class. Flat ground should read below the robot's threshold and traversable; a hazard
//! should never read traversable.

use std::collections::BTreeMap;
use std::path::Path;

use serde::{Deserialize, Serialize};
use tre_core::geometry::Grid;
use tre_core::roughness::noise::SensorNoise;
use tre_core::roughness::traversal::Traversal;
use tre_pipeline::{FrameInput, Pipeline, PipelineConfig};

use super::{frame_sensor, load_frame, RealFrame};
use crate::error::{read_json, BenchError, JsonFileError, RunError};

/// The regions file.
#[derive(Debug, Clone, Deserialize)]
pub struct RegionFile {
    /// How the regions were picked.
    pub rule: String,
    /// Each set's sensor class and noise model (the class names the table's rows; the model
    /// overrides the set's camera file, whose `sensor` may be only the nearest preset).
    pub sensors: BTreeMap<String, SetSensor>,
    /// The frames with regions.
    pub frames: Vec<RegionFrame>,
}

/// A set's sensor class and noise model.
#[derive(Debug, Clone, Deserialize)]
pub struct SetSensor {
    /// The sensor class: `kinect`, `lidar`, `lidar_accumulated`, `passive_stereo`, …
    pub class: String,
    /// Its noise model (a preset name or `{"sigma_mm": [a, b, c]}`).
    pub sensor: SensorNoise,
}

/// One frame's regions.
#[derive(Debug, Clone, Deserialize)]
pub struct RegionFrame {
    /// The set's folder name.
    pub set: String,
    /// The depth path as the set's frame list names it.
    pub depth: String,
    /// Known-flat ground.
    #[serde(default)]
    pub flat: Vec<Region>,
    /// Known hazards (bands across a discontinuity at ground level).
    #[serde(default)]
    pub hazard: Vec<Region>,
}

/// A box `[x0, y0, x1, y1)` in pixels of the stored frame.
#[derive(Debug, Clone, Deserialize)]
pub struct Region {
    /// The box.
    #[serde(rename = "box")]
    pub rect: [usize; 4],
}

impl RegionFile {
    /// Reads a regions file.
    ///
    /// # Errors
    ///
    /// When it does not read or parse.
    pub fn read(path: &Path) -> Result<Self, JsonFileError> {
        read_json(path)
    }

    fn frame(&self, f: &RealFrame) -> Option<&RegionFrame> {
        self.frames
            .iter()
            .find(|r| r.set == f.sequence && r.depth == f.depth_rel)
    }
}

/// The figures of one row (a configuration) on one sensor class.
#[derive(Debug, Clone, Default, Serialize)]
pub struct RegionFigures {
    /// Frames with regions.
    pub frames: usize,
    /// … of which with gravity known (stated, or a confident ground plane): the three-state
    /// figures count these frames only, since without gravity no pixel can be traversable.
    pub gravity_frames: usize,
    /// Flat pixels with depth.
    pub flat_px: usize,
    /// … of which with a roughness reading.
    pub flat_read: usize,
    /// … read ≥ 5 cm.
    pub flat_rough: usize,
    /// Flat pixels with depth in frames with gravity.
    pub flat_px_gravity: usize,
    /// … read traversable / hazard / unknown (three-state).
    pub flat_states: [usize; 3],
    /// Hazard pixels with depth.
    pub hazard_px: usize,
    /// Hazard pixels with depth in frames with gravity.
    pub hazard_px_gravity: usize,
    /// … read traversable / hazard / unknown (three-state).
    pub hazard_states: [usize; 3],
    /// Hazard boxes, and those where some pixel reads hazard (three-state) or ≥ 5 cm.
    pub hazard_boxes: (usize, usize),
    /// The same, in frames with gravity.
    pub hazard_boxes_gravity: (usize, usize),
}

/// Every row's figures per sensor class: `rows[row][class]`.
#[derive(Debug, Clone, Default, Serialize)]
pub struct RegionReport {
    /// The row names, in order.
    pub names: Vec<String>,
    /// Per row, per class.
    pub rows: Vec<BTreeMap<String, RegionFigures>>,
}

/// Scores `rows` on the regions of `frames` (frames without regions are skipped); `default`:
/// the noise model of a set the file does not list and whose camera names none.
///
/// # Errors
///
/// When a frame does not read or a configuration fails on it.
pub fn score_regions(
    frames: &[RealFrame],
    file: &RegionFile,
    rows: &[(String, PipelineConfig)],
    pipeline: &mut Pipeline,
    default: &SensorNoise,
) -> Result<RegionReport, BenchError> {
    let mut report = RegionReport {
        names: rows.iter().map(|(n, _)| n.clone()).collect(),
        rows: vec![BTreeMap::new(); rows.len()],
    };
    for frame in frames {
        let Some(regions) = file.frame(frame) else {
            continue;
        };
        let set = file.sensors.get(&frame.sequence);
        let sensor = set.map_or_else(|| frame_sensor(frame, default), |s| s.sensor);
        let class = set.map_or_else(|| "unlisted".to_owned(), |s| s.class.clone());
        let mut loaded = load_frame(frame).map_err(|source| BenchError::Load {
            frame: frame.name(),
            source: Box::new(source),
        })?;
        loaded.input.sensor = Some(sensor);
        for ((key, cfg), acc) in rows.iter().zip(&mut report.rows) {
            let fig = acc.entry(class.clone()).or_default();
            score_row(pipeline, (&loaded.input, regions), cfg, fig).map_err(|source| {
                BenchError::Run {
                    frame: frame.name(),
                    row: key.clone(),
                    source: Box::new(source),
                }
            })?;
        }
    }
    Ok(report)
}

/// Runs one configuration on a frame (its input carries the sensor's noise model) and adds
/// its figures on the frame's regions to `fig`.
fn score_row(
    pipeline: &mut Pipeline,
    (input, regions): (&FrameInput, &RegionFrame),
    cfg: &PipelineConfig,
    fig: &mut RegionFigures,
) -> Result<(), RunError> {
    let depth = input.depth_m.as_ref().ok_or(RunError::NoSensorDepth)?;
    let out = pipeline.run(input, cfg)?;
    let table = pipeline.interval_table_for(cfg);
    let maps = out.sensor_maps(input, cfg.mode, input.sensor.as_ref(), None, table)?;
    fig.frames += 1;
    let gravity = out.gravity.up_in_cam().is_some();
    fig.gravity_frames += usize::from(gravity);
    add_regions(
        fig,
        regions,
        depth,
        (&out.roughness_m, &maps.traversal, gravity),
    );
    pipeline.recycle(out);
    Ok(())
}

/// Adds one frame's regions to `fig`.
fn add_regions(
    fig: &mut RegionFigures,
    regions: &RegionFrame,
    depth: &Grid<f64>,
    (roughness_m, traversal, gravity): (&Grid<f64>, &Grid<Traversal>, bool),
) {
    let state = |t: Traversal| match t {
        Traversal::Traversable => 0,
        Traversal::Hazard => 1,
        Traversal::Unknown => 2,
    };
    for r in &regions.flat {
        for (x, y) in pixels(r, depth) {
            fig.flat_px += 1;
            let v = roughness_m[(x, y)];
            if v.is_finite() {
                fig.flat_read += 1;
                fig.flat_rough += usize::from(v >= 0.05);
            }
            if gravity {
                fig.flat_px_gravity += 1;
                fig.flat_states[state(traversal[(x, y)])] += 1;
            }
        }
    }
    for r in &regions.hazard {
        let mut seen = false;
        for (x, y) in pixels(r, depth) {
            fig.hazard_px += 1;
            let t = traversal[(x, y)];
            if gravity {
                fig.hazard_px_gravity += 1;
                fig.hazard_states[state(t)] += 1;
            }
            seen |= t == Traversal::Hazard || roughness_m[(x, y)] >= 0.05;
        }
        fig.hazard_boxes.0 += 1;
        fig.hazard_boxes.1 += usize::from(seen);
        if gravity {
            fig.hazard_boxes_gravity.0 += 1;
            fig.hazard_boxes_gravity.1 += usize::from(seen);
        }
    }
}

/// The pixels of a region's box that have depth.
fn pixels<'a>(r: &Region, depth: &'a Grid<f64>) -> impl Iterator<Item = (usize, usize)> + 'a {
    let [x0, y0, x1, y1] = r.rect;
    let (w, h) = depth.size();
    (y0.min(h)..y1.min(h))
        .flat_map(move |y| (x0.min(w)..x1.min(w)).map(move |x| (x, y)))
        .filter(|&(x, y)| {
            let d = depth[(x, y)];
            d.is_finite() && d > 0.0
        })
}

/// The report as markdown: one table for flat regions, one for hazards.
pub fn regions_markdown(report: &RegionReport) -> String {
    let pct = |a: usize, b: usize| {
        if b == 0 {
            "-".to_owned()
        } else {
            format!("{:.1}%", 100.0 * a as f64 / b as f64)
        }
    };
    let mut s = String::from(
        "Known-flat regions (truth: ground flat by eye; shares of the pixels with depth; the \
         three states in the frames with gravity)\n\n\
         | row | sensor class | frames (with gravity) | flat px | read | read >= 5 cm | traversable | hazard | unknown |\n\
         | --- | --- | ---: | ---: | ---: | ---: | ---: | ---: | ---: |\n",
    );
    for (name, classes) in report.names.iter().zip(&report.rows) {
        for (class, f) in classes {
            let [t, h, u] = f.flat_states;
            s += &format!(
                "| {name} | {class} | {} ({}) | {} | {} | {} | {} | {} | {} |\n",
                f.frames,
                f.gravity_frames,
                f.flat_px,
                pct(f.flat_read, f.flat_px),
                pct(f.flat_rough, f.flat_read),
                pct(t, f.flat_px_gravity),
                pct(h, f.flat_px_gravity),
                pct(u, f.flat_px_gravity),
            );
        }
    }
    s += "\nKnown hazards (truth: bands across a step, a drop or an object's foot, by eye; the \
          three states in the frames with gravity; a box is seen where a pixel reads hazard or \
          >= 5 cm)\n\n\
          | row | sensor class | hazard px | read traversable | hazard | unknown | boxes seen | seen, frames with gravity |\n\
          | --- | --- | ---: | ---: | ---: | ---: | ---: | ---: |\n";
    for (name, classes) in report.names.iter().zip(&report.rows) {
        for (class, f) in classes {
            let [t, h, u] = f.hazard_states;
            let (boxes, seen) = f.hazard_boxes;
            let (gboxes, gseen) = f.hazard_boxes_gravity;
            s += &format!(
                "| {name} | {class} | {} | {} | {} | {} | {seen}/{boxes} ({}) | {gseen}/{gboxes} ({}) |\n",
                f.hazard_px,
                pct(t, f.hazard_px_gravity),
                pct(h, f.hazard_px_gravity),
                pct(u, f.hazard_px_gravity),
                pct(seen, boxes),
                pct(gseen, gboxes),
            );
        }
    }
    s
}
