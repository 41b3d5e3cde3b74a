//! Calibrated roughness intervals of every mode fitted on real frames of a split
//! (docs/uncertainty.md), as `tre calibrate` writes them beside the models
//! (`uncertainty.json`).
//!
//! Samples: every `stride`-th pixel (in x and y) with spec roughness. `rgb`: the reading,
//! its 7×7 maximum and the depth net's depth, against the spec on the sensor depth. `rgbd`:
//! the same with the sensor model's uncertainty instead of depth. `geometric`: the spec's own
//! reading and uncertainty, against the spec of the same surface in the previous frame of a
//! sequence with poses (pixels the two frames share, docs/uncertainty.md).

use std::collections::BTreeMap;

use tre_core::geometry::Grid;
use tre_core::roughness::interval::{
    feature_map, FirstAxis, IntervalTable, Sample, SecondAxis, COVERAGE,
};
use tre_core::roughness::noise::SensorNoise;
use tre_pipeline::{FrameOutput, Mode, Pipeline, PipelineConfig};

use crate::error::{BenchError, RunError};
use crate::real::{self, LoadedFrame, OtherView, Pose, PrevView, RealFrame};

/// A sample with its block (see [`block_of`]).
type Tagged = (usize, Sample);

/// Samples of each configuration calibrated, under the key of its table
/// ([`PipelineConfig::interval_key`]) and with its mode, each tagged with its block of frames.
#[derive(Debug, Default)]
pub struct Samples {
    sets: Vec<(&'static str, Mode, Vec<Tagged>)>,
}

/// Frames per block of a long sequence.
const BLOCK_FRAMES: usize = 10;
/// Percentile levels tried, narrowest first.
const LEVELS: [f64; 7] = [0.90, 0.92, 0.94, 0.96, 0.97, 0.98, 0.99];
/// Fewest samples a block needs to be held out.
const MIN_BLOCK_SAMPLES: usize = 2_000;

/// The block of a frame: its sequence, and within a long sequence every [`BLOCK_FRAMES`]
/// frames of the list.
fn block_of(blocks: &mut Vec<(String, usize)>, frame: &RealFrame) -> usize {
    let key = (frame.sequence.clone(), frame.index / BLOCK_FRAMES);
    match blocks.iter().position(|b| *b == key) {
        Some(i) => i,
        None => {
            blocks.push(key);
            blocks.len() - 1
        }
    }
}

/// The narrowest level of [`LEVELS`] whose table, fitted without one block, covers 90% of
/// that block's samples on average over the blocks (each block counts once); with its
/// held-out coverage. `None`: fewer than two blocks to hold out.
fn held_out_level(axes: (FirstAxis, SecondAxis), samples: &[Tagged]) -> Option<(f64, f64)> {
    let mut blocks: Vec<usize> = samples.iter().map(|&(b, _)| b).collect();
    blocks.sort_unstable();
    blocks.dedup();
    let held: Vec<(Vec<Sample>, Vec<Sample>)> = blocks
        .iter()
        .map(|&b| {
            let (inn, out): (Vec<&Tagged>, Vec<&Tagged>) =
                samples.iter().partition(|(x, _)| *x == b);
            let strip = |v: Vec<&Tagged>| v.into_iter().map(|x| x.1).collect::<Vec<_>>();
            (strip(inn), strip(out))
        })
        .filter(|(inn, _): &(Vec<Sample>, Vec<Sample>)| inn.len() >= MIN_BLOCK_SAMPLES)
        .collect();
    if held.len() < 2 {
        return None;
    }
    let mut last = None;
    for level in LEVELS {
        let covs: Vec<f64> = held
            .iter()
            .filter_map(|(inn, out)| {
                Some(IntervalTable::fit_level(axes, out, level)?.coverage_of(inn))
            })
            .collect();
        let mean = covs.iter().sum::<f64>() / covs.len().max(1) as f64;
        last = Some((level, mean));
        if mean >= COVERAGE {
            break;
        }
    }
    last
}

impl Samples {
    /// Every mode's samples on `frames` (`sensor`: the noise model of sequences that name
    /// none; every `stride`-th pixel in x and y).
    ///
    /// # Errors
    ///
    /// When a frame does not read or a mode fails on it.
    pub fn collect(
        frames: &[RealFrame],
        pipeline: &mut Pipeline,
        cfgs: &[PipelineConfig],
        sensor: &SensorNoise,
        stride: usize,
    ) -> Result<Samples, BenchError> {
        let mut samples = Samples {
            sets: cfgs
                .iter()
                .filter_map(|c| Some((c.interval_key()?, c.mode, Vec::new())))
                .collect(),
        };
        let mut previous: Option<PrevView> = None;
        let mut blocks = Vec::new();
        for (i, frame) in frames.iter().enumerate() {
            let block = block_of(&mut blocks, frame);
            let load_error = |source| BenchError::Load {
                frame: frame.name(),
                source: Box::new(source),
            };
            let loaded = real::load_frame(frame).map_err(load_error)?;
            let frame_sensor = real::frame_sensor(frame, sensor);
            let pose = Pose::of(frame).map_err(|e| load_error(e.into()))?;
            let shared = real::shared_with(previous.as_ref(), frame, pose, &loaded);
            for cfg in cfgs {
                let views = (&loaded, shared.as_ref());
                let s = mode_samples(pipeline, cfg, views, &frame_sensor, stride).map_err(
                    |source| BenchError::Run {
                        frame: frame.name(),
                        row: cfg.label(),
                        source: Box::new(source),
                    },
                )?;
                let s = s.into_iter().map(|x| (block, x));
                if let Some(set) = samples
                    .sets
                    .iter_mut()
                    .find(|x| Some(x.0) == cfg.interval_key())
                {
                    set.2.extend(s);
                }
            }
            tracing::info!("{}/{} frames: {}", i + 1, frames.len(), frame.name());
            previous = pose.map(|pose| PrevView::new(frame, pose, loaded));
        }
        Ok(samples)
    }
}

/// Runs one mode on a loaded frame; its samples against the spec on the same depth, or for
/// `geometric` against the spec of the same surface in the other view (none without one).
fn mode_samples(
    pipeline: &mut Pipeline,
    cfg: &PipelineConfig,
    (loaded, other): (&LoadedFrame, Option<&OtherView>),
    sensor: &SensorNoise,
    stride: usize,
) -> Result<Vec<Sample>, RunError> {
    let out = pipeline.run(&loaded.input, cfg)?;
    let target = match (cfg.mode, other) {
        (Mode::Geometric, None) => None,
        (Mode::Geometric, Some(other)) => Some(other.targets()),
        _ => Some(loaded.spec.roughness_m.clone()),
    };
    let samples = match target {
        Some(target) => samples_of(&out, loaded, (cfg.mode, sensor), &target, stride),
        None => Ok(Vec::new()),
    };
    pipeline.recycle(out);
    samples
}

/// The samples of one mode's output on a frame against `target` (NaN: none).
fn samples_of(
    out: &FrameOutput,
    loaded: &LoadedFrame,
    (mode, sensor): (Mode, &SensorNoise),
    target: &Grid<f64>,
    stride: usize,
) -> Result<Vec<Sample>, RunError> {
    let r = &out.roughness_m;
    let second = match mode {
        Mode::Rgb => out.depth_m().ok_or(RunError::NoPredictedDepth { mode })?,
        _ => {
            out.sensor_maps(&loaded.input, mode, Some(sensor), None, None)?
                .uncertainty_m
        }
    };
    let depth = match mode {
        Mode::Rgb => out.depth_m().ok_or(RunError::NoPredictedDepth { mode })?,
        _ => loaded
            .input
            .depth_m
            .clone()
            .ok_or(RunError::NoSensorDepth)?,
    };
    let feature = feature_map(first_axis(mode), r, &depth);
    let (w, h) = r.size();
    let step = stride.max(1);
    let mut v = Vec::new();
    for y in (0..h).step_by(step) {
        for x in (0..w).step_by(step) {
            let (reading_m, target_m) = (r[(x, y)], target[(x, y)]);
            if reading_m.is_finite() && target_m.is_finite() {
                v.push(Sample {
                    feature_m: feature[(x, y)],
                    second: second[(x, y)],
                    reading_m,
                    target_m,
                });
            }
        }
    }
    Ok(v)
}

/// Each mode's table at its held-out level (the narrowest level whose held-out coverage reaches 90%), with a line per mode
/// saying what it took.
#[must_use]
pub fn fit_tables(samples: &Samples) -> (BTreeMap<String, IntervalTable>, Vec<String>) {
    let mut tables = BTreeMap::new();
    let mut lines = Vec::new();
    for (key, mode, s) in &samples.sets {
        let axis = match mode {
            Mode::Rgb => SecondAxis::Depth,
            Mode::Rgbd | Mode::Geometric => SecondAxis::Uncertainty,
        };
        let axes = (first_axis(*mode), axis);
        let (level, held) = held_out_level(axes, s).unwrap_or((COVERAGE, f64::NAN));
        let all: Vec<Sample> = s.iter().map(|x| x.1).collect();
        let Some(t) = IntervalTable::fit_level(axes, &all, level) else {
            lines.push(format!("{key}: {} samples, too few for a table", s.len()));
            continue;
        };
        let own = t.own.iter().filter(|&&o| o).count();
        lines.push(format!(
            "{key}: {} samples, {own} bins of their own; percentiles of {:.0}%, held-out \
             coverage {:.1}%",
            s.len(),
            100.0 * level,
            100.0 * held
        ));
        tables.insert((*key).to_owned(), t);
    }
    (tables, lines)
}

/// The first feature of each mode's table: the learned modes add their depth's steps (the
/// spec marks every step, a net may read one flat); `geometric` is the spec, its reading is
/// enough.
fn first_axis(mode: Mode) -> FirstAxis {
    match mode {
        Mode::Geometric => FirstAxis::Reading,
        Mode::Rgb | Mode::Rgbd => FirstAxis::ReadingOrStep,
    }
}
