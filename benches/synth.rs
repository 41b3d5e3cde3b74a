//! Criterion benches of the synthetic dataset generator at 512×512 on the paper's camera:
//! rendering one view, annotating it, and a whole frame written to disk; rendering (natural,
//! indoor and urban scenes) and each depth-sensor model at 640×480.
#![allow(missing_docs)] // criterion_group! generates undocumented items.

use criterion::{criterion_group, criterion_main, Criterion};
use tre::geometry::Intrinsics;
use tre::roughness::annotate::{annotate, AnnotateConfig, AnnotateInput};
use tre::roughness::noise::SensorPreset;
use tre::synth::dataset::{build_scene, scene_views, view_conditions};
use tre::synth::sensor::{simulate, SensorInput, SensorModel};
use tre::synth::{content::Content, dataset::SynthConfig, render, Conditions, RenderedFrame, View};

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
    let k640 = Intrinsics::from_hfov(640, 480, 60.0).expect("valid hfov");
    let view640 = View {
        intrinsics: k640,
        width: 640,
        height: 480,
        ..views[4]
    };
    sensors_640(c, &render(&scene, &view640, &cond), &k640);
    c.bench_function("synth/render_640x480", |b| {
        b.iter(|| render(&scene, &view640, &cond))
    });
    contents_640(c, &views, &view640, &cond);
    let dir = tempfile::tempdir().expect("temp dir");
    let one = SynthConfig {
        out: dir.path().to_owned(),
        scenes: 1,
        ..SynthConfig::default()
    };
    c.bench_function("synth/scene_9_frames_on_disk", |b| {
        b.iter(|| tre::synth::dataset::generate(&one).expect("writes"))
    });
}

/// Each depth-sensor model on a 640×480 frame.
fn sensors_640(c: &mut Criterion, f640: &RenderedFrame, k640: &Intrinsics) {
    for sensor in [
        SensorPreset::KinectV1,
        SensorPreset::RealsenseD435,
        SensorPreset::AzureKinect,
        SensorPreset::Lidar,
    ] {
        let model = SensorModel::preset(sensor);
        let input = SensorInput {
            depth_m: &f640.depth_m,
            normals_cam: &f640.normals_cam,
            rgb: &f640.rgb,
            intrinsics: k640,
        };
        c.bench_function(&format!("synth/sensor_{sensor}_640x480"), |b| {
            b.iter(|| simulate(&model, &input, 1))
        });
    }
}

/// Rendering the indoor and urban scenes at 640×480.
fn contents_640(c: &mut Criterion, views: &[View], view640: &View, cond: &Conditions) {
    for content in [Content::Indoor, Content::Urban] {
        let cfg = SynthConfig {
            content,
            ..SynthConfig::default()
        };
        let scene = build_scene(&cfg, 0, views);
        c.bench_function(&format!("synth/render_640x480_{content}"), |b| {
            b.iter(|| render(&scene, view640, cond))
        });
    }
}

criterion_group! {
    name = benches;
    config = Criterion::default().sample_size(10).measurement_time(std::time::Duration::from_secs(5));
    targets = synth
}
criterion_main!(benches);
