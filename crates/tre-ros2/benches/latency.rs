//! End-to-end latency of the ROS 2 node: a second node publishes the kitchen sequence's real
//! 640×480 depth frames (16UC1) with camera_info at 15 frames/s, stamped when sent; the
//! latency of a frame is the time from that stamp to the arrival of its roughness image.
//! In the same run: the same frames through [`Processor::process`] alone (the node's work
//! without DDS) and through the pipeline alone (`tre infer`'s work without file I/O), so the
//! node's own cost is the difference. `cargo bench -p tre-ros2 --bench latency`
//! (`TRE_BENCH_SECONDS`, default 30; `TRE_SHARED_DIR` for the frames).
#![allow(clippy::unwrap_used, clippy::print_stdout)] // A bench fails loudly and prints.

use std::path::PathBuf;
use std::time::{Duration, Instant, SystemTime, UNIX_EPOCH};

use ros2_client::qos::{History, Reliability, WhenFull};
use ros2_client::{
    Context, ContextOptions, MessageTypeName, Name, NodeName, NodeOptions, QosProfile,
};
use tre_core::roughness::noise::{SensorNoise, SensorPreset};
use tre_pipeline::{FrameInput, Mode, Pipeline, PipelineConfig};
use tre_record::encode::depth_mm_image;
use tre_record::msgs::{CameraInfo, Header, Image, RosMessage, Time};
use tre_ros2::{FrameMsgs, ImageOutputs, NodeConfig, Processor};

fn shared() -> PathBuf {
    match std::env::var_os("TRE_SHARED_DIR") {
        Some(d) if !d.is_empty() => PathBuf::from(d),
        _ => PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../../shared"),
    }
}

fn now() -> Time {
    let d = SystemTime::now().duration_since(UNIX_EPOCH).unwrap();
    Time::from_nanos(d.as_nanos() as i64)
}

fn frames() -> Vec<Image> {
    let dir = shared().join("data/real-rgbd-2/sevenscenes_redkitchen/depth");
    let mut paths: Vec<_> = std::fs::read_dir(&dir)
        .unwrap_or_else(|e| panic!("{}: {e} (set TRE_SHARED_DIR)", dir.display()))
        .map(|e| e.unwrap().path())
        .collect();
    paths.sort();
    paths
        .iter()
        .take(30)
        .map(|p| depth_mm_image(&Header::default(), &image::open(p).unwrap().to_luma16()))
        .collect()
}

fn info(img: &Image) -> CameraInfo {
    CameraInfo {
        width: img.width,
        height: img.height,
        k: [585.0, 0.0, 320.0, 0.0, 585.0, 240.0, 0.0, 0.0, 1.0],
        ..CameraInfo::default()
    }
}

fn pct(v: &mut [f64], p: f64) -> f64 {
    v.sort_by(f64::total_cmp);
    v[((v.len() - 1) as f64 * p).round() as usize]
}

fn processor() -> Processor {
    let cfg = PipelineConfig {
        mode: Mode::Geometric,
        ..PipelineConfig::default()
    };
    let sensor = SensorNoise::Preset(SensorPreset::KinectV1);
    Processor::new(Pipeline::new(None), cfg, Some(sensor), None).with_images(ImageOutputs::all())
}

/// The same frames in-process, after a warm-up round: the node's processing and the
/// pipeline alone, milliseconds.
fn in_process(frames: &[Image], k: &CameraInfo) -> (Vec<f64>, Vec<f64>) {
    let mut p = processor();
    let (mut node_ms, mut pipe_ms) = (Vec::new(), Vec::new());
    let mut pipeline = Pipeline::new(None);
    let cfg = *p.config();
    for round in 0..3 {
        for f in frames {
            let msgs = FrameMsgs {
                depth: Some(f.clone()),
                colour: None,
                info: Some(k.clone()),
                pose: None,
            };
            let t = Instant::now();
            drop(p.process(&msgs).unwrap());
            let dt = t.elapsed().as_secs_f64() * 1e3;
            let input = FrameInput {
                rgb: None,
                depth_m: Some(tre_ros2::convert::depth_m(f).unwrap()),
                intrinsics: Some(tre_ros2::convert::intrinsics(k, f).unwrap()),
                mounting: None,
                sensor: None,
            };
            let t = Instant::now();
            let out = pipeline.run(&input, &cfg).unwrap();
            let dp = t.elapsed().as_secs_f64() * 1e3;
            pipeline.recycle(out);
            if round > 0 {
                node_ms.push(dt);
                pipe_ms.push(dp);
            }
        }
    }
    (node_ms, pipe_ms)
}

/// A peer node on `domain`: depth and camera_info publishers, a roughness subscription,
/// matched with the node under test.
fn peer(
    domain: u16,
) -> (
    Context,
    ros2_client::Node,
    ros2_client::Publisher<Image>,
    ros2_client::Publisher<CameraInfo>,
    ros2_client::Subscription<Image>,
) {
    let ctx = Context::with_options(ContextOptions::new().domain_id(domain)).unwrap();
    let mut peer = ctx
        .new_node(NodeName::new("/", "tre_bench").unwrap(), NodeOptions::new())
        .unwrap();
    let q = QosProfile::publisher_default()
        .reliability(Reliability::Reliable {
            when_full: WhenFull::DEFAULT,
        })
        .history(History::KeepLast { depth: 1 });
    let topic = |peer: &mut ros2_client::Node, name: &str, t: (&str, &str)| {
        peer.create_topic(
            &Name::parse(name).unwrap(),
            MessageTypeName::new(t.0, t.1),
            &q,
        )
        .unwrap()
    };
    let t = topic(
        &mut peer,
        "/camera/depth/image_rect_raw",
        (Image::PACKAGE, Image::NAME),
    );
    let depth_pub = peer.create_publisher::<Image>(&t, Some(q.clone())).unwrap();
    let t = topic(
        &mut peer,
        "/camera/depth/camera_info",
        (CameraInfo::PACKAGE, CameraInfo::NAME),
    );
    let info_pub = peer
        .create_publisher::<CameraInfo>(&t, Some(q.clone()))
        .unwrap();
    let t = topic(&mut peer, "/tre/roughness", (Image::PACKAGE, Image::NAME));
    let sub = peer
        .create_subscription::<Image>(&t, Some(q.clone()))
        .unwrap();
    let spinner = peer.spinner().unwrap();
    std::thread::Builder::new()
        .name("bench-spin".into())
        .spawn(move || futures::executor::block_on(spinner.spin()))
        .unwrap();
    let deadline = Instant::now() + Duration::from_secs(30);
    while depth_pub.get_subscription_count(&peer) == 0 || sub.get_publisher_count(&peer) == 0 {
        assert!(
            Instant::now() < deadline,
            "no discovery in 30 s (multicast needed)"
        );
        std::thread::sleep(Duration::from_millis(20));
    }
    (ctx, peer, depth_pub, info_pub, sub)
}

/// Publishes `total` frames at 15 frames/s stamped when sent; the latency of every answer.
fn over_dds(frames: &[Image], k: &CameraInfo, total: usize) -> (Vec<f64>, u64) {
    let domain = 150 + (std::process::id() % 60) as u16;
    let config = NodeConfig {
        domain_id: domain,
        ..NodeConfig::default()
    };
    let node = tre_ros2::start(config, processor()).unwrap();
    let (_ctx, _peer, depth_pub, info_pub, sub) = peer(domain);
    std::thread::sleep(Duration::from_millis(500));
    info_pub.publish(k.clone()).unwrap();
    std::thread::sleep(Duration::from_millis(200));
    let period = Duration::from_secs_f64(1.0 / 15.0);
    let mut lat_ms = Vec::new();
    let start = Instant::now();
    let mut sent = 0;
    while sent < total || Instant::now() < start + period * (sent as u32) + Duration::from_secs(1) {
        if sent < total && Instant::now() >= start + period * sent as u32 {
            let mut f = frames[sent % frames.len()].clone();
            f.header.stamp = now();
            depth_pub.publish(f).unwrap();
            sent += 1;
        }
        while let Ok(Some((m, _))) = sub.take() {
            lat_ms.push((now().nanos() - m.header.stamp.nanos()) as f64 * 1e-6);
        }
        std::thread::sleep(Duration::from_micros(500));
    }
    let dropped = node
        .stats()
        .dropped
        .load(std::sync::atomic::Ordering::Relaxed);
    let _ = node.stop();
    (lat_ms, dropped)
}

fn main() {
    let seconds: f64 = std::env::var("TRE_BENCH_SECONDS")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(30.0);
    let frames = frames();
    let k = info(&frames[0]);
    let (mut n, mut pp) = in_process(&frames, &k);
    let warm = 15;
    let total = (seconds * 15.0) as usize + warm;
    let (lat_ms, dropped) = over_dds(&frames, &k, total);
    let answered = lat_ms.len();
    let mut m: Vec<f64> = lat_ms.iter().skip(warm.min(answered)).copied().collect();
    println!("ROS 2 node, geometric, 640x480 kitchen depth frames at 15 frames/s for {seconds} s:");
    println!("  sent {total}, answered {answered}, dropped as stale {dropped}");
    println!(
        "  latency stamp -> roughness received: p50 {:.1} ms, p90 {:.1} ms, p99 {:.1} ms, max {:.1} ms ({} frames after {warm} warm-up)",
        pct(&mut m, 0.5), pct(&mut m, 0.9), pct(&mut m, 0.99), pct(&mut m, 1.0), m.len()
    );
    println!(
        "  in-process, same frames: the node's processing (decode, pipeline, sensor maps, encode) p50 {:.1} ms; the pipeline alone (tre infer's work) p50 {:.1} ms",
        pct(&mut n, 0.5), pct(&mut pp, 0.5)
    );
}
