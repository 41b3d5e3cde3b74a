//! Seed inputs: small images, the JPEG fixtures, the real frames, `.npy` files, cameras,
//! multipart bodies and stream messages, each accepted by its entry point.

use std::io::Write;
use std::path::{Path, PathBuf};
use std::sync::OnceLock;

use image::{DynamicImage, ImageBuffer};
use prost::Message;

use tre_io::npy::{write_npy, F16};
use tre_proto::v1 as pb;

/// The real frames, `../shared/data/real-rgbd` beside the repository (or under
/// `$TRE_SHARED_DIR`), where they are there. Where they are not, their seeds are left out and
/// one line on stderr (past the harness's capture) says so, unless `TRE_REQUIRE_SHARED=1` (as
/// in CI), which makes the missing folder a failure. The rule of `tests/it/common/mod.rs`.
fn real_rgbd() -> Option<&'static Path> {
    static DIR: OnceLock<Option<PathBuf>> = OnceLock::new();
    DIR.get_or_init(|| {
        let root = match std::env::var_os("TRE_SHARED_DIR") {
            Some(dir) if !dir.is_empty() => PathBuf::from(dir),
            _ => Path::new(env!("CARGO_MANIFEST_DIR")).join("../../../shared"),
        };
        let dir = root.join("data/real-rgbd");
        if dir.is_dir() {
            return Some(dir);
        }
        if std::env::var("TRE_REQUIRE_SHARED").is_ok_and(|v| v == "1") {
            panic!(
                "TRE_REQUIRE_SHARED=1: ../shared/data/real-rgbd is required beside the repository, and {} is missing",
                dir.display()
            );
        }
        let line = format!(
            "skipped the real-frame fuzz seeds: they need ../shared/data/real-rgbd beside the repository ({} is missing)\n",
            dir.display()
        );
        let _ = std::io::stderr().write_all(line.as_bytes());
        None
    })
    .as_deref()
}

/// A file of the real frames, where they are there ([`real_rgbd`]).
fn shared(rel: &str) -> Option<Vec<u8>> {
    let path = real_rgbd()?.join(rel);
    Some(std::fs::read(&path).unwrap_or_else(|e| panic!("{}: {e}", path.display())))
}

fn fixture(rel: &str) -> Vec<u8> {
    let path = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../../tests/fixtures")
        .join(rel);
    std::fs::read(&path).unwrap_or_else(|e| panic!("{}: {e}", path.display()))
}

fn png(img: DynamicImage) -> Vec<u8> {
    let mut out = Vec::new();
    tre_io::encode_png(&img, &mut out).unwrap();
    out
}

/// A small 16-bit depth PNG (millimetres, 0.5–2.5 m, a few holes).
pub(super) fn small_depth(w: u32, h: u32) -> Vec<u8> {
    png(DynamicImage::ImageLuma16(ImageBuffer::from_fn(
        w,
        h,
        |x, y| {
            image::Luma([if (x + y) % 7 == 0 {
                0
            } else {
                (500 + 40 * x + 30 * y) as u16
            }])
        },
    )))
}

pub(super) fn small_pngs() -> Vec<Vec<u8>> {
    vec![
        png(DynamicImage::ImageRgb8(ImageBuffer::from_fn(
            13,
            7,
            |x, y| image::Rgb([x as u8 * 19, y as u8 * 30, 7]),
        ))),
        png(DynamicImage::ImageRgba8(ImageBuffer::from_fn(
            5,
            9,
            |x, y| image::Rgba([x as u8, y as u8, 3, 200]),
        ))),
        png(DynamicImage::ImageLuma8(ImageBuffer::from_fn(
            16,
            16,
            |x, y| image::Luma([(x * y) as u8]),
        ))),
        png(DynamicImage::ImageRgb16(ImageBuffer::from_fn(
            6,
            4,
            |x, y| image::Rgb([x as u16 * 999, y as u16, 65535]),
        ))),
        small_depth(17, 11),
    ]
}

pub(super) fn jpegs() -> Vec<Vec<u8>> {
    let names = [
        "baseline_420.jpg",
        "baseline_444.jpg",
        "cmyk.jpg",
        "grey.jpg",
        "progressive.jpg",
        "restart.jpg",
        "trailing_bytes.jpg",
    ];
    names
        .iter()
        .map(|n| fixture(&format!("jpeg/{n}")))
        .collect()
}

/// The real frames: a Kinect colour PNG and depth PNG, an NYU JPEG and depth PNG.
fn real_frames() -> Vec<Vec<u8>> {
    [
        "slambook2_ch7/1.png",
        "slambook2_ch7/1_depth.png",
        "metric3d_nyu/rgb/rgb_00000.jpg",
        "metric3d_nyu/depth/sync_depth_00000.png",
    ]
    .iter()
    .filter_map(|r| shared(r))
    .collect()
}

/// The small images, then `more`, then the real frames: the seeds of an entry point that takes
/// images.
pub(super) fn with_images(more: Vec<Vec<u8>>) -> Vec<Vec<u8>> {
    let mut seeds = small_pngs();
    seeds.extend(more);
    seeds.extend(real_frames());
    seeds
}

pub(super) fn npys() -> Vec<Vec<u8>> {
    let mut out = Vec::new();
    let depth: Vec<f32> = (0..48).map(|i| 0.5 + i as f32 * 0.01).collect();
    let mut add = |f: &dyn Fn(&mut Vec<u8>)| {
        let mut v = Vec::new();
        f(&mut v);
        out.push(v);
    };
    add(&|v| write_npy(v, &[6, 8], &depth).unwrap());
    add(&|v| write_npy(v, &[48], &depth).unwrap());
    add(&|v| write_npy(v, &[2, 3, 8], &depth).unwrap());
    add(&|v| {
        let d: Vec<F16> = depth.iter().map(|&x| F16::from_f32(x)).collect();
        write_npy(v, &[8, 6], &d).unwrap();
    });
    add(&|v| {
        let d: Vec<f64> = depth.iter().map(|&x| f64::from(x)).collect();
        write_npy(v, &[4, 12], &d).unwrap();
    });
    add(&|v| write_npy(v, &[4, 4], &[1000u16; 16]).unwrap());
    out
}

pub(super) fn camera_json() -> Vec<u8> {
    br#"{"fx": 520.9, "fy": 521.0, "cx": 325.1, "cy": 249.7, "width": 17, "height": 11, "depth_scale": 1000.0, "pitch_deg": 10.0, "height_m": 0.5, "sensor": "kinect_v1"}"#.to_vec()
}

pub(super) fn cameras() -> Vec<Vec<u8>> {
    let mut out = vec![
        camera_json(),
        br#"{"fx": 500, "fy": 500, "cx": 8, "cy": 5}"#.to_vec(),
        br#"{"fx": 500, "fy": 500, "cx": 8, "cy": 5, "sensor": {"sigma_mm": [1.0, 0.5, 2.0]}}"#
            .to_vec(),
    ];
    out.extend(
        [
            "slambook2_ch7/intrinsics.json",
            "slambook2_ch5/intrinsics.json",
            "metric3d_nyu/intrinsics.json",
        ]
        .iter()
        .filter_map(|r| shared(r)),
    );
    out
}

/// A multipart body of [`crate::fuzzing::MULTIPART_TYPE`] with these parts.
fn multipart_body(parts: &[(&str, &[u8])]) -> Vec<u8> {
    let mut body = Vec::new();
    for (name, bytes) in parts {
        body.extend_from_slice(b"--tre-fuzz-Boundary\r\n");
        body.extend_from_slice(
            format!("Content-Disposition: form-data; name=\"{name}\"; filename=\"{name}\"\r\n")
                .as_bytes(),
        );
        body.extend_from_slice(b"Content-Type: application/octet-stream\r\n\r\n");
        body.extend_from_slice(bytes);
        body.extend_from_slice(b"\r\n");
    }
    body.extend_from_slice(b"--tre-fuzz-Boundary--\r\n");
    body
}

pub(super) fn multipart_bodies() -> Vec<Vec<u8>> {
    let rgb = &small_pngs()[0];
    let depth = small_depth(13, 7);
    let npy = &npys()[0];
    let camera = br#"{"fx": 20, "fy": 20, "cx": 6.5, "cy": 3.5, "depth_scale": 1000}"#;
    let mut out = vec![
        multipart_body(&[("rgb", rgb), ("depth", &depth), ("camera", camera)]),
        multipart_body(&[("depth", &depth)]),
        multipart_body(&[("depth", npy), ("camera", camera)]),
        multipart_body(&[("rgb", &jpegs()[0])]),
    ];
    if let (Some(rgb), Some(depth)) = (
        shared("slambook2_ch7/1.png"),
        shared("slambook2_ch7/1_depth.png"),
    ) {
        let camera = br#"{"fx": 520.9, "fy": 521.0, "cx": 325.1, "cy": 249.7, "width": 640, "height": 480, "depth_scale": 5000.0}"#;
        out.push(multipart_body(&[
            ("rgb", &rgb),
            ("depth", &depth),
            ("camera", camera),
        ]));
    }
    out
}

fn pb_camera() -> pb::Camera {
    pb::Camera {
        fx: 20.0,
        fy: 20.0,
        cx: 6.5,
        cy: 3.5,
        depth_scale: Some(1000.0),
        width: Some(13),
        height: Some(7),
        sensor: Some("kinect_v1".into()),
        ..pb::Camera::default()
    }
}

pub(super) fn client_message(msg: pb::client_message::Msg) -> Vec<u8> {
    pb::ClientMessage { msg: Some(msg) }.encode_to_vec()
}

pub(super) fn stream_messages() -> Vec<Vec<u8>> {
    use pb::client_message::Msg;
    let frame = |image: Vec<u8>, depth: Vec<u8>, camera: Option<pb::Camera>| {
        client_message(Msg::Frame(pb::Frame {
            sequence: 7,
            timestamp_us: 1_700_000_000_000_000,
            image,
            depth,
            camera,
            pose: Vec::new(),
        }))
    };
    vec![
        client_message(Msg::Hello(pb::Hello {
            camera: Some(pb_camera()),
            mode: 2,
            format: 1,
            dsac_hypotheses: 4,
            max_roughness_cm: Some(5.0),
            want_traversable: true,
            ..pb::Hello::default()
        })),
        frame(
            small_pngs()[0].clone(),
            small_depth(13, 7),
            Some(pb_camera()),
        ),
        frame(Vec::new(), npys()[0].clone(), None),
        frame(jpegs()[1].clone(), Vec::new(), None),
    ]
}
