//! Criterion benches of the synthetic dataset generator at 512×512 on the paper's camera:
//! rendering one view, annotating it, and a whole frame written to disk.
#![allow(missing_docs)] // criterion_group! generates undocumented items.

use criterion::{criterion_group, criterion_main, Criterion};
use tre::roughness::{annotate, AnnotateConfig, AnnotateInput};
use tre::synth::dataset::{build_scene, scene_views, view_conditions};
use tre::synth::{render, SynthConfig};

fn synth(c: &mut Criterion) {
    let cfg = SynthConfig::default();
    let views = scene_views(&cfg, 0);
    let scene = build_scene(&cfg, 0, &views);
    let cond = view_conditions(&cfg, 0, 4);
    c.bench_function("synth/scene_grid", |b| {
        b.iter(|| build_scene(&cfg, 0, &views))
    });
    c.bench_function("synth/render_512", |b| {
        b.iter(|| render(&scene, &views[4], &cond))
    });
    let f = render(&scene, &views[4], &cond);
    c.bench_function("synth/annotate_512", |b| {
        b.iter(|| {
            let input = AnnotateInput {
                depth_m: &f.depth_m,
                intrinsics: &views[4].intrinsics,
                normals: Some(&f.normals_cam),
                labels: Some(&f.labels),
            };
            annotate(&input, &AnnotateConfig::default()).expect("ground in view")
        })
    });
    let dir = tempfile::tempdir().expect("temp dir");
    let one = SynthConfig {
        out: dir.path().to_owned(),
        scenes: 1,
        ..SynthConfig::default()
    };
    c.bench_function("synth/scene_9_frames_on_disk", |b| {
        b.iter(|| tre::synth::generate(&one).expect("writes"))
    });
}

criterion_group! {
    name = benches;
    config = Criterion::default().sample_size(10).measurement_time(std::time::Duration::from_secs(5));
    targets = synth
}
criterion_main!(benches);
