//! Criterion benches of one frame through the whole pipeline, per mode, for synthetic frames of
//! 256×256 and 512×512 (the networks run at 256 on the long side either way), with the split by
//! stage printed after each bench from the pipeline's own stage timings; the same at 256×256 as
//! a server worker does it (PNG bytes decoded, the pipeline, the 16-bit roughness PNG encoded);
//! the LS normals alone against the same right after a net run; and the geometric mode (the
//! annotation spec) on a real Kinect frame at 640×480 and 256×192 beside `tre annotate`, with
//! the cost of its uncertainty and three-state maps.
#![allow(missing_docs)] // criterion_group! generates undocumented items.

use std::collections::BTreeMap;
use std::path::Path;
use std::time::{Duration, Instant};

use criterion::measurement::WallTime;
use criterion::{criterion_group, criterion_main, BenchmarkGroup, Criterion};
use image::DynamicImage;
use ndarray::Array4;
use tre::geometry::normals::{local_planes_into, PackedPoints};
use tre::geometry::normals::{LocalPlanes, Neighbourhood};
use tre::io::{depth_png16, encode_png, read_camera, read_depth, CameraFile};
use tre::model::{Models, SessionConfig};
use tre::pipeline::resize::resize_nearest;
use tre::pipeline::{
    CentroidMethod, FrameInput, GeometricMethod, Method, Mode, NormalsMethod, Pipeline,
    PipelineConfig, StageTimings,
};
use tre::roughness::annotate::{annotate, AnnotateConfig, AnnotateInput};
use tre::roughness::noise::{SensorNoise, SensorPreset};
use tre::server::options::FrameOptions;
use tre::server::request::{
    assumptions, config_for, decode_frame, encode_reply, DecodeLimits, FrameDefaults, FrameRequest,
};
use tre::synth::dataset::{build_scene, scene_views, view_conditions};
use tre::synth::{dataset::SynthConfig, render};

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
        mounting: Some(view.mounting),
        sensor: None,
    }
}

/// The configurations benched: (name, config); `_k4`: DSAC with 4 hypotheses instead of 12.
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
        (
            "rgb_k4",
            PipelineConfig {
                dsac_hypotheses: 4,
                ..full(Mode::Rgb)
            },
        ),
        ("rgbd", full(Mode::Rgbd)),
        (
            "rgbd_k4",
            PipelineConfig {
                dsac_hypotheses: 4,
                ..full(Mode::Rgbd)
            },
        ),
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
    let mut split = Split::default();
    for _ in 0..n {
        let out = pipeline.run(input, cfg).expect("the frame runs");
        split.add_timings(&out.timings);
        pipeline.recycle(out);
    }
    split.report()
}

/// Benches one frame through the pipeline as `id` in `group` (named `group_name`), then prints
/// its stage split.
fn run_frame(
    group: &mut BenchmarkGroup<'_, WallTime>,
    pipeline: &mut Pipeline,
    (group_name, id): (&str, &str),
    input: &FrameInput,
    cfg: &PipelineConfig,
) {
    // Criterion calls the closure only for benches the command line selects; the split follows
    // only those.
    let mut ran = false;
    group.bench_function(id, |b| {
        ran = true;
        b.iter(|| {
            let out = pipeline.run(input, cfg).expect("the frame runs");
            pipeline.recycle(out);
        })
    });
    if ran {
        eprintln!(
            "{group_name}/{id} by stage: {}",
            stage_split(pipeline, input, cfg, 10)
        );
    }
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
            run_frame(
                &mut group,
                &mut pipeline,
                ("pipeline", &format!("{name}_{side}")),
                &input,
                &cfg,
            );
        }
    }
    group.finish();
}

/// `frame` as a client sends it: PNG bytes (RGB; depth as 16-bit millimetres when `depth`) and
/// the camera as JSON fields.
fn request(frame: &FrameInput, depth: bool, normals: NormalsMethod) -> FrameRequest {
    let png = |img: &DynamicImage| {
        let mut out = Vec::new();
        encode_png(img, &mut out).expect("encodes");
        out
    };
    let k = frame
        .intrinsics
        .expect("the synthetic frame has intrinsics");
    let depth_m = frame
        .depth_m
        .as_ref()
        .expect("the synthetic frame has depth");
    FrameRequest {
        rgb: frame
            .rgb
            .clone()
            .map(|rgb| png(&DynamicImage::ImageRgb8(rgb))),
        depth: depth.then(|| png(&DynamicImage::ImageLuma16(depth_png16(depth_m)))),
        camera: Some(CameraFile {
            fx: k.fx_px,
            fy: k.fy_px,
            cx: k.cx_px,
            cy: k.cy_px,
            width: None,
            height: None,
            depth_scale: Some(1000.0),
            pitch_deg: frame.mounting.map(|m| m.pitch_rad.to_degrees()),
            height_m: frame.mounting.map(|m| m.height_m),
            sensor: None,
        }),
        options: FrameOptions {
            normals: Some(normals),
            ..FrameOptions::default()
        },
        map: None,
    }
}

const LIMITS: DecodeLimits = DecodeLimits {
    max_pixels: 50_000_000,
    max_side: 16384,
    max_aspect: 8,
};

/// What a server worker does with one request (`run_job`): decode, choose the configuration,
/// run, encode; the split adds decode and encode to the pipeline's stages.
fn serve_one(pipeline: &mut Pipeline, req: &FrameRequest, split: &mut Split) {
    let t = Instant::now();
    let frame = decode_frame(req, LIMITS).expect("decodes");
    let cfg = config_for(
        &frame,
        &req.options,
        LIMITS.max_pixels,
        FrameDefaults::default(),
    );
    let decoded = t.elapsed();
    let out = pipeline.run(&frame, &cfg).expect("the frame runs");
    let t = Instant::now();
    let facts = (cfg.mode, assumptions(req, &frame, cfg.mode));
    let reply = encode_reply(&out, &req.options, facts).expect("encodes");
    pipeline.recycle(out);
    split.add("decode", decoded);
    split.add("encode", t.elapsed());
    split.add_timings(&reply.timings);
}

/// Stage times summed over runs.
#[derive(Default)]
struct Split {
    sums: BTreeMap<&'static str, Duration>,
    onnx: Duration,
    runs: u32,
}

impl Split {
    fn add(&mut self, name: &'static str, took: Duration) {
        *self.sums.entry(name).or_default() += took;
    }

    /// Adds one run's stage timings and ONNX Runtime time, and counts the run.
    fn add_timings(&mut self, timings: &StageTimings) {
        for (name, took) in timings.iter() {
            self.add(name, took);
        }
        self.onnx += timings.onnx_runtime();
        self.runs += 1;
    }

    /// Mean milliseconds per stage and the share outside ONNX Runtime.
    fn report(&self) -> String {
        let ms = |d: Duration| d.as_secs_f64() * 1e3 / f64::from(self.runs);
        let total: f64 = self.sums.values().map(|&d| ms(d)).sum();
        let onnx = ms(self.onnx);
        let parts: Vec<String> = self
            .sums
            .iter()
            .map(|(k, &v)| format!("{k} {:.1}", ms(v)))
            .collect();
        format!(
            "total {total:.1} ms = {}; inside ONNX Runtime {onnx:.1} ms, outside {:.1} ms ({:.0}%)",
            parts.join(", "),
            total - onnx,
            100.0 * (total - onnx) / total
        )
    }
}

fn requests(c: &mut Criterion) {
    let models_dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("models");
    let models = Models::load(&models_dir, &SessionConfig::default()).expect("models load");
    let mut pipeline = Pipeline::new(Some(models));
    let input = frame(256);
    // (name, with RGB, with depth, initial normals)
    let cases = [
        ("rgb", true, false, NormalsMethod::Dsac),
        ("rgb_ls", true, false, NormalsMethod::Ls),
        ("rgbd", true, true, NormalsMethod::Dsac),
        ("geometric", false, true, NormalsMethod::Ls),
    ];
    let mut group = c.benchmark_group("request");
    group.sample_size(20);
    for (name, rgb, depth, normals) in cases {
        let mut req = request(&input, depth, normals);
        if !rgb {
            req.rgb = None;
        }
        let mut ran = false;
        group.bench_function(format!("{name}_256"), |b| {
            ran = true;
            b.iter(|| serve_one(&mut pipeline, &req, &mut Split::default()))
        });
        if ran {
            let mut split = Split::default();
            for _ in 0..10 {
                serve_one(&mut pipeline, &req, &mut split);
            }
            eprintln!("request/{name}_256 by stage: {}", split.report());
        }
    }
    group.finish();
}

/// LS normals and window centroids of the depth net's points at 256×256 (`rgb_ls`'s normals
/// stage, into buffers reused across calls as the pipeline does), timed alone (after the same
/// call) and right after a depth-net run, which leaves the caches holding the net's
/// activations.
fn ls_after_net(c: &mut Criterion) {
    let models_dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("models");
    let mut models = Models::load(&models_dir, &SessionConfig::default()).expect("models load");
    let input = frame(256);
    let k = input
        .intrinsics
        .expect("the synthetic frame has intrinsics");
    let points = k.back_project_map(input.depth_m.as_ref().expect("depth"));
    let rgb = Array4::<f32>::from_elem((1, 3, 256, 256), 0.5);
    let prior = Array4::<f32>::from_elem((1, 1, 256, 256), 1.5);
    let hood = Neighbourhood::default();
    let (mut packed, mut planes) = (PackedPoints::default(), LocalPlanes::default());
    let mut ls = move || {
        local_planes_into(&points, k.fx_px, &hood, &mut packed, &mut planes);
        std::hint::black_box(&planes);
    };
    let mut group = c.benchmark_group("ls_normals_256");
    group.sample_size(30);
    group.bench_function("alone", |b| b.iter(&mut ls));
    group.bench_function("after_depth_net", |b| {
        b.iter_custom(|iters| {
            let mut took = Duration::ZERO;
            for _ in 0..iters {
                models
                    .depth(rgb.view(), prior.view())
                    .expect("the net runs");
                let t = Instant::now();
                ls();
                took += t.elapsed();
            }
            took
        })
    });
    group.finish();
}

/// The TUM fr2 Kinect frame of `../shared/data/real-rgbd/slambook2_ch7` as depth-only input,
/// at its own 640×480 and resampled (nearest) to `size` with the intrinsics scaled.
fn real_depth_frame(size: (usize, usize)) -> FrameInput {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../shared/data/real-rgbd/slambook2_ch7");
    let (_, k) = read_camera(&dir.join("intrinsics.json")).expect("the shared intrinsics read");
    let depth = read_depth(&dir.join("1_depth.png"), 5000.0).expect("the shared depth reads");
    let (w0, h0) = depth.size();
    let k = k
        .scaled(size.0 as f64 / w0 as f64, size.1 as f64 / h0 as f64)
        .expect("a valid scale");
    FrameInput {
        depth_m: Some(resize_nearest(&depth, size.0, size.1, 0.0)),
        intrinsics: Some(k),
        ..FrameInput::default()
    }
}

/// The geometric mode on a real Kinect frame at its own 640×480 and at 256×192: the terrain
/// estimate (`terrain`, the default, under the Kinect v1 model, its uncertainty included), the
/// whole annotation spec (`spec`) and its sensor maps, the paper's surface-only baseline, and
/// `tre annotate`'s library call on the same depth for comparison.
fn geometric_real(c: &mut Criterion) {
    let mut pipeline = Pipeline::new(None);
    let mut group = c.benchmark_group("geometric_real");
    group.sample_size(30);
    let kinect = SensorNoise::Preset(SensorPreset::KinectV1);
    for (w, h) in [(640, 480), (256, 192)] {
        let input = FrameInput {
            sensor: Some(kinect),
            ..real_depth_frame((w, h))
        };
        for (name, geometric) in [
            ("terrain", GeometricMethod::Terrain),
            ("spec", GeometricMethod::Spec),
            ("surface_only", GeometricMethod::SurfaceOnly),
        ] {
            let cfg = PipelineConfig {
                geometric,
                ..PipelineConfig::for_mode(Mode::Geometric)
            };
            run_frame(
                &mut group,
                &mut pipeline,
                ("geometric_real", &format!("{name}_{w}x{h}")),
                &input,
                &cfg,
            );
        }
        // The uncertainty and three-state maps (Kinect v1), on top of the spec's output and of
        // the terrain estimate's (whose uncertainty came with it).
        for (name, geometric) in [
            ("sensor_maps", GeometricMethod::Spec),
            ("terrain_sensor_maps", GeometricMethod::Terrain),
        ] {
            let cfg = PipelineConfig {
                geometric,
                ..PipelineConfig::for_mode(Mode::Geometric)
            };
            let out = pipeline.run(&input, &cfg).expect("the frame runs");
            group.bench_function(format!("{name}_{w}x{h}"), |b| {
                b.iter(|| {
                    out.sensor_maps(&input, Mode::Geometric, Some(&kinect), None, None)
                        .expect("maps")
                })
            });
        }
        let depth = input.depth_m.as_ref().expect("depth");
        let k = input.intrinsics.expect("intrinsics");
        let ann = AnnotateInput::depth(depth, &k);
        group.bench_function(format!("annotate_{w}x{h}"), |b| {
            b.iter(|| annotate(&ann, &AnnotateConfig::default()).expect("annotates"))
        });
    }
    group.finish();
}

/// Fusing one real 640×480 Kinect depth frame into the grid map (4 cm cells, 8 m × 8 m: the
/// indoor preset), and reading every layer of the map (roughness, slope and step from the
/// fused surface).
fn map_fusion(c: &mut Criterion) {
    use tre::geometry::floor::{fit_floor, FloorFitConfig};
    use tre::map::{GridMap, MapConfig, MapFrame, MapLimits, Pose};
    let input = real_depth_frame((640, 480));
    let k = input.intrinsics.expect("intrinsics");
    let points = k.back_project_map(input.depth_m.as_ref().expect("depth"));
    let fit = fit_floor(&points, &FloorFitConfig::default()).expect("a ground");
    let frame = MapFrame::from_gravity(&-fit.up_in_cam).expect("a frame");
    let kinect = SensorNoise::Preset(SensorPreset::KinectV1);
    let mut map = GridMap::new(MapConfig::default(), frame, (0.0, 0.0)).expect("a map");
    let mut group = c.benchmark_group("map");
    group.sample_size(30);
    let mut t = 0.0;
    group.bench_function("fuse_640x480", |b| {
        b.iter(|| {
            t += 1.0;
            map.fuse(&points, &Pose::identity(), t, &kinect)
                .expect("fuses")
        });
    });
    group.bench_function("layers_200x200", |b| {
        b.iter(|| map.layers(&MapLimits::default()));
    });
    group.finish();
}

/// The 16-bit roughness PNG of the spec on the real Kinect frame, at 640×480 and 256×192, with
/// each of the PNG filters (fast compression), `encode_png` (what the service and `tre infer`
/// write) beside them; the sizes printed once.
fn png_encode(c: &mut Criterion) {
    use image::codecs::png::{CompressionType, FilterType, PngEncoder};
    let mut pipeline = Pipeline::new(None);
    let mut group = c.benchmark_group("png");
    group.sample_size(30);
    let cfg = PipelineConfig {
        geometric: GeometricMethod::Spec,
        ..PipelineConfig::for_mode(Mode::Geometric)
    };
    for (w, h) in [(640, 480), (256, 192)] {
        let out = pipeline
            .run(&real_depth_frame((w, h)), &cfg)
            .expect("the spec runs");
        let img = DynamicImage::ImageLumaA16(tre::io::roughness_png16(&out.roughness_m));
        let filters = [
            ("adaptive", FilterType::Adaptive),
            ("none", FilterType::NoFilter),
            ("sub", FilterType::Sub),
            ("up", FilterType::Up),
            ("avg", FilterType::Avg),
            ("paeth", FilterType::Paeth),
        ];
        for (name, filter) in filters {
            let encode = || {
                let mut bytes = Vec::new();
                let enc = PngEncoder::new_with_quality(&mut bytes, CompressionType::Fast, filter);
                img.write_with_encoder(enc).expect("encodes");
                bytes
            };
            println!("png/{name}_{w}x{h}: {} bytes", encode().len());
            group.bench_function(format!("{name}_{w}x{h}"), |b| b.iter(encode));
        }
        group.bench_function(format!("encode_png_{w}x{h}"), |b| {
            b.iter(|| {
                let mut bytes = Vec::new();
                encode_png(&img, &mut bytes).expect("encodes");
                bytes
            })
        });
    }
    group.finish();
}

criterion_group!(
    benches,
    pipeline,
    requests,
    ls_after_net,
    geometric_real,
    map_fusion,
    png_encode
);
criterion_main!(benches);
