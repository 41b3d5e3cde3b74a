//! Criterion benches of the geometry kernels: LS normals on a real 640×480 Kinect frame, DSAC
//! normals (K = 12) at 256×256 and 512×512 (each also into buffers reused from the call before,
//! as the pipeline runs them), and the whole annotator.

#![allow(missing_docs)] // criterion_group! generates undocumented items.

use std::path::Path;

use criterion::{criterion_group, criterion_main, BenchmarkId, Criterion};
use tre::geometry::dsac::{dsac_normals, dsac_normals_into, DsacConfig, DsacScratch, CANDIDATES};
use tre::geometry::normals::{local_planes_into, PackedPoints};
use tre::geometry::raycast::{render_depth, MarchConfig};
use tre::geometry::{
    normals::{ls_normals, LocalPlanes, Neighbourhood},
    Grid, Intrinsics, Mounting, PointMap,
};
use tre::roughness::annotate::{annotate, AnnotateConfig, AnnotateInput};

fn kinect_frame() -> (Grid<f64>, Intrinsics) {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../shared/data/real-rgbd/metric3d_nyu");
    let (cam, k) = tre::io::read_camera(&dir.join("intrinsics.json")).expect("camera");
    let depth = tre::io::read_depth(
        &dir.join("depth/sync_depth_00000.png"),
        cam.depth_scale.unwrap_or(1000.0),
    )
    .expect("depth");
    (depth, k)
}

/// Gravel-like terrain seen by the paper's robot camera (1 m, 60° down).
fn terrain_points(size: usize) -> PointMap {
    let k = Intrinsics::from_hfov(size, size, 60.0).expect("camera");
    let field =
        |x: f64, y: f64| 0.01 * ((x * 37.0).sin() * (y * 41.0).cos()) + 0.05 * (y * 3.0).sin();
    let depth = render_depth(
        &field,
        &k,
        &Mounting::default(),
        (size, size),
        &MarchConfig::default(),
    );
    k.back_project_map(&depth)
}

/// Neighbour-net logits for a `size`×`size` frame: a fixed pseudo-random pattern.
fn bench_logits(size: usize) -> Vec<f32> {
    (0..CANDIDATES * size * size)
        .map(|i| ((i * 2654435761usize) % 997) as f32 / 300.0)
        .collect()
}

fn ls(c: &mut Criterion) {
    let (depth, k) = kinect_frame();
    let pts = k.back_project_map(&depth);
    let hood = Neighbourhood::default();
    c.bench_function("ls_normals/640x480_kinect", |b| {
        b.iter(|| ls_normals(&pts, k.fx_px, &hood))
    });
    // As the pipeline runs it frame after frame: into buffers kept from the call before.
    let (mut packed, mut planes) = (PackedPoints::default(), LocalPlanes::default());
    c.bench_function("ls_normals/640x480_kinect_reused", |b| {
        b.iter(|| local_planes_into(&pts, k.fx_px, &hood, &mut packed, &mut planes))
    });
}

fn dsac(c: &mut Criterion) {
    let mut g = c.benchmark_group("dsac_normals_k12");
    for size in [256usize, 512] {
        let pts = terrain_points(size);
        let logits = bench_logits(size);
        let cfg = DsacConfig {
            seed: 1,
            ..Default::default()
        };
        g.bench_with_input(
            BenchmarkId::from_parameter(format!("{size}x{size}")),
            &size,
            |b, _| b.iter(|| dsac_normals(&pts, &logits, &cfg).expect("sizes match")),
        );
        let (mut scratch, mut out) = (DsacScratch::default(), Grid::default());
        g.bench_with_input(
            BenchmarkId::from_parameter(format!("{size}x{size}_reused")),
            &size,
            |b, _| {
                b.iter(|| {
                    dsac_normals_into(&pts, &logits, &cfg, &mut scratch, &mut out)
                        .expect("sizes match")
                })
            },
        );
    }
    g.finish();
    // Fewer hypotheses (`--dsac-hypotheses`), into reused buffers, at the pipeline's size.
    let mut g = c.benchmark_group("dsac_normals_256x256_reused");
    let size = 256;
    let pts = terrain_points(size);
    let logits = bench_logits(size);
    let (mut scratch, mut out) = (DsacScratch::default(), Grid::default());
    for k in [1u32, 2, 4, 6, 8, 12] {
        let cfg = DsacConfig {
            seed: 1,
            hypotheses: k,
            ..Default::default()
        };
        g.bench_with_input(BenchmarkId::new("k", k), &k, |b, _| {
            b.iter(|| {
                dsac_normals_into(&pts, &logits, &cfg, &mut scratch, &mut out).expect("sizes match")
            })
        });
    }
    g.finish();
}

fn annotator(c: &mut Criterion) {
    let (depth, k) = kinect_frame();
    c.bench_function("annotate/640x480_kinect", |b| {
        b.iter(|| {
            let input = AnnotateInput::depth(&depth, &k);
            annotate(&input, &AnnotateConfig::default()).expect("valid frame")
        })
    });
}

criterion_group! {
    name = benches;
    config = Criterion::default().sample_size(15).measurement_time(std::time::Duration::from_secs(4));
    targets = ls, dsac, annotator
}
criterion_main!(benches);
