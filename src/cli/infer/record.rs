//! The JSON record `tre infer` writes beside its maps (`<stem>.json`): what ran (mode, stages,
//! gravity), what stood in for what was not given, the sensor, the models' hashes, the timings
//! and the files, so that the maps keep their meaning when shared without the console.

use std::path::{Path, PathBuf};

use serde_json::{json, Value};

use crate::model::Manifest;
use crate::pipeline::{models_key, Assumption, FrameOutput, Gravity, PipelineConfig, SensorMaps};

/// The version of the record's layout.
pub(crate) const RECORD_FORMAT: u32 = 1;

/// What a run of `tre infer` was given and what came of it, for [`record`].
pub(crate) struct Run<'a> {
    /// The frame, depth and camera files given.
    pub inputs: [Option<&'a Path>; 3],
    /// The configuration that ran, and whether its mode was asked for.
    pub cfg: (&'a PipelineConfig, bool),
    /// The pipeline's output.
    pub out: &'a FrameOutput,
    /// What stood in for what was not given, and the other warnings, in words.
    pub said: (&'a [Assumption], &'a [String]),
    /// The noise model's label, and the camera's free-text sensor.
    pub sensor: (Option<String>, Option<&'a str>),
    /// The depth PNG's units per metre and whether they were stated.
    pub depth_scale: Option<(f64, bool)>,
    /// The models' manifest, if models were loaded.
    pub models: Option<&'a Manifest>,
    /// The sensor maps, when written.
    pub maps: Option<&'a SensorMaps>,
    /// Each file written and, for a preview, its title.
    pub files: &'a [(PathBuf, Option<String>)],
}

/// The path of the record of the map `out`: `<stem>.json` beside it.
pub(crate) fn record_path(out: &Path) -> PathBuf {
    out.with_extension("json")
}

/// The record of `run` as JSON.
pub(crate) fn record(run: &Run<'_>) -> Value {
    let (cfg, mode_asked) = run.cfg;
    let [frame, depth, camera] = run.inputs.map(|p| p.map(|p| p.display().to_string()));
    let (assumed, warnings) = run.said;
    json!({
        "format": RECORD_FORMAT,
        "tre_version": env!("CARGO_PKG_VERSION"),
        "inputs": { "frame": frame, "depth": depth, "camera": camera },
        "mode": cfg.mode.to_string(),
        "mode_asked": mode_asked,
        "method": cfg.method.to_string(),
        "stages": cfg.label(),
        "stage_names": cfg.stage_names(),
        "size": run.out.roughness_m.size(),
        "working_size": run.out.working_size,
        "gravity": gravity(&run.out.gravity),
        "assumptions": assumed
            .iter()
            .map(|a| json!({ "key": a.key(), "words": a.to_string() }))
            .collect::<Vec<_>>(),
        "warnings": warnings,
        "sensor": { "noise_model": run.sensor.0, "described": run.sensor.1 },
        "depth_scale": run.depth_scale.map(|(units, stated)| {
            json!({ "units_per_m": units, "stated": stated })
        }),
        "models": run.models.map(models),
        "roughness": roughness(run.out),
        "three_state": run.maps.map(three_state),
        "timings_ms": timings(run.out),
        "files": run
            .files
            .iter()
            .map(|(p, title)| json!({ "path": p.display().to_string(), "title": title }))
            .collect::<Vec<_>>(),
    })
}

/// Where gravity came from, its figures, and the line the console prints.
fn gravity(g: &Gravity) -> Value {
    let figures = g.figures().map(|f| {
        json!({
            "pitch_deg": f.pitch_deg,
            "roll_deg": f.roll_deg,
            "height_m": f.height_m,
            "support": f.support,
        })
    });
    json!({ "source": g.source(), "figures": figures, "line": g.to_string() })
}

/// The models' key (as `tre calibrate` records it) and each model's file and SHA-256.
fn models(m: &Manifest) -> Value {
    let each: serde_json::Map<String, Value> = m
        .models
        .iter()
        .map(|(name, e)| {
            let entry = json!({ "file": e.file, "sha256": e.sha256 });
            (name.clone(), entry)
        })
        .collect();
    json!({ "key": models_key(m), "each": each })
}

/// Pixels with roughness and their median, metres.
fn roughness(out: &FrameOutput) -> Value {
    let valid = crate::roughness::metrics::finite_sorted(&out.roughness_m);
    let median = valid.get(valid.len() / 2).copied();
    json!({ "pixels": valid.len(), "median_m": median })
}

/// The three states' shares, and the caveat of a map mostly unknown.
fn three_state(maps: &SensorMaps) -> Value {
    let (t, h, u) = crate::roughness::traversal::shares(&maps.traversal);
    json!({
        "traversable": t,
        "hazard": h,
        "unknown": u,
        "caveat": maps.mostly_unknown(),
    })
}

/// Milliseconds per stage, in the order they ran, and in all.
fn timings(out: &FrameOutput) -> Value {
    let ms = |d: std::time::Duration| d.as_secs_f64() * 1e3;
    let stages: Vec<Value> = out
        .timings
        .iter()
        .map(|(name, d)| json!({ "stage": name, "ms": ms(d) }))
        .collect();
    json!({
        "stages": stages,
        "onnx_runtime": ms(out.timings.onnx_runtime()),
        "total": ms(out.timings.total()),
    })
}
