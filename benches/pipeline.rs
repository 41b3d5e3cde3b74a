//! Criterion benches of one frame through the whole pipeline, per mode, for synthetic frames of
//! 256×256 and 512×512 (the networks run at 256 on the long side either way), with the split by
//! stage printed after each bench from the pipeline's own stage timings.
#![allow(missing_docs)] // criterion_group! generates undocumented items.

use std::collections::BTreeMap;
use std::path::Path;

use criterion::{criterion_group, criterion_main, Criterion};
use tre::model::{Models, SessionConfig};
use tre::pipeline::{
    CentroidMethod, FrameInput, Method, Mode, NormalsMethod, Pipeline, PipelineConfig,
};
use tre::synth::dataset::{build_scene, scene_views, view_conditions};
use tre::synth::{render, SynthConfig};

/// A rendered synthetic frame of `side`×`side` as pipeline input (RGB, depth, camera, mounting).
fn frame(side: usize) -> FrameInput {
    let cfg = SynthConfig {
        size: (side, side),
        ..SynthConfig::default()
    };
    let views = scene_views(&cfg, 0);
    let scene = build_scene(&cfg, 0, &views);
    let view = &views[4];
    let f = render(&scene, view, &view_conditions(&cfg, 0, 4));
    FrameInput {
        rgb: Some(f.rgb),
        depth_m: Some(f.depth_m),
        intrinsics: Some(view.intrinsics),
        mounting: view.mounting,
    }
}

/// The configurations benched: (name, config).
fn configs() -> Vec<(&'static str, PipelineConfig)> {
    let full = |mode| PipelineConfig::for_mode(mode);
    vec![
        ("rgb", full(Mode::Rgb)),
        (
            "rgb_ls",
            PipelineConfig {
                normals: NormalsMethod::Ls,
                ..full(Mode::Rgb)
            },
        ),
        ("rgbd", full(Mode::Rgbd)),
        ("geometric", full(Mode::Geometric)),
        (
            "end_to_end",
            PipelineConfig {
                method: Method::EndToEnd,
                centroid: CentroidMethod::Net,
                ..full(Mode::Rgb)
            },
        ),
    ]
}

/// Mean milliseconds per stage over `n` runs, their total, and the share of the total spent
/// outside ONNX Runtime (resize, tensor packing, geometry, outputs).
fn stage_split(
    pipeline: &mut Pipeline,
    input: &FrameInput,
    cfg: &PipelineConfig,
    n: u32,
) -> String {
    let mut sums: BTreeMap<String, f64> = BTreeMap::new();
    let mut onnx = 0.0;
    for _ in 0..n {
        let out = pipeline.run(input, cfg).expect("the frame runs");
        for (name, took) in out.timings.iter() {
            *sums.entry(name.to_owned()).or_default() += took.as_secs_f64() * 1e3 / f64::from(n);
        }
        onnx += out.timings.onnx_runtime().as_secs_f64() * 1e3 / f64::from(n);
    }
    let total: f64 = sums.values().sum();
    let parts: Vec<String> = sums.iter().map(|(k, v)| format!("{k} {v:.1}")).collect();
    format!(
        "total {total:.1} ms = {}; inside ONNX Runtime {onnx:.1} ms, outside {:.1} ms ({:.0}%)",
        parts.join(", "),
        total - onnx,
        100.0 * (total - onnx) / total
    )
}

fn pipeline(c: &mut Criterion) {
    let models_dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("models");
    let models = Models::load(&models_dir, &SessionConfig::default()).expect("models load");
    let mut pipeline = Pipeline::new(Some(models));
    let mut group = c.benchmark_group("pipeline");
    group.sample_size(20);
    for side in [256, 512] {
        let input = frame(side);
        for (name, cfg) in configs() {
            group.bench_function(format!("{name}_{side}"), |b| {
                b.iter(|| pipeline.run(&input, &cfg).expect("the frame runs"))
            });
            eprintln!(
                "pipeline/{name}_{side} by stage: {}",
                stage_split(&mut pipeline, &input, &cfg, 10)
            );
        }
    }
    group.finish();
}

criterion_group!(benches, pipeline);
criterion_main!(benches);
