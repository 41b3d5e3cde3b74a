//! Fuzzing on stable Rust: property tests that feed each entry point of [`super`] arbitrary bytes
//! and mutations of real inputs (the frames in `../shared/data/real-rgbd`, the JPEG fixtures,
//! small images, `.npy` files, cameras, multipart bodies and stream messages made here), and
//! bound what each case may allocate. The case counts keep the whole module to seconds;
//! `TRE_FUZZ_SCALE=N` runs N times as many, and the `cargo fuzz` targets in `fuzz/` are the
//! longer run.

use std::path::Path;
use std::sync::Arc;
use std::time::Instant;

use image::{DynamicImage, ImageBuffer};
use proptest::prelude::*;
use prost::Message;

use tre_io::npy::{write_npy, F16};
use tre_proto::v1 as pb;

/// The system allocator, counting each thread's live bytes and their peak, for the whole lib
/// test binary (frees on another thread than the allocation only make a count drift).
mod counting {
    // A global allocator is unsafe by its trait's definition; this one forwards every call to
    // the system's unchanged and only counts sizes.
    #![allow(unsafe_code)]

    use std::alloc::{GlobalAlloc, Layout, System};
    use std::cell::Cell;

    thread_local! {
        static LIVE: Cell<isize> = const { Cell::new(0) };
        static PEAK: Cell<isize> = const { Cell::new(0) };
    }

    fn add(bytes: isize) {
        let _ = LIVE.try_with(|live| {
            let now = live.get() + bytes;
            live.set(now);
            let _ = PEAK.try_with(|peak| peak.set(peak.get().max(now)));
        });
    }

    struct Counting;

    // SAFETY: every method forwards to `System` with the caller's arguments unchanged.
    unsafe impl GlobalAlloc for Counting {
        unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
            // SAFETY: the caller's contract is `System`'s.
            let p = unsafe { System.alloc(layout) };
            if !p.is_null() {
                add(layout.size() as isize);
            }
            p
        }

        unsafe fn alloc_zeroed(&self, layout: Layout) -> *mut u8 {
            // SAFETY: as `alloc`.
            let p = unsafe { System.alloc_zeroed(layout) };
            if !p.is_null() {
                add(layout.size() as isize);
            }
            p
        }

        unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
            // SAFETY: as `alloc`.
            unsafe { System.dealloc(ptr, layout) };
            add(-(layout.size() as isize));
        }

        unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
            // SAFETY: as `alloc`.
            let p = unsafe { System.realloc(ptr, layout, new_size) };
            if !p.is_null() {
                add(new_size as isize - layout.size() as isize);
            }
            p
        }
    }

    #[global_allocator]
    static ALLOCATOR: Counting = Counting;

    /// Runs `f` and returns the most bytes this thread held at once during it, above what it
    /// held before.
    pub fn peak_during(f: impl FnOnce()) -> usize {
        let base = LIVE.with(Cell::get);
        PEAK.with(|p| p.set(base));
        f();
        usize::try_from(PEAK.with(Cell::get) - base).unwrap_or(0)
    }
}

/// The most one case may allocate at once: the decoder's own cap at the default 4 Mi pixels
/// (16 B per pixel), the frame's converted maps, and a few copies of the input.
fn allocation_bound(input: usize) -> usize {
    let pixels = super::limits().max_pixels;
    pixels * 16 + pixels * 24 + 8 * input + (16 << 20)
}

/// Runs `entry` on `data`, checking the allocation bound; returns whether it was accepted, the
/// case's time and its peak.
fn run_case(entry: fn(&[u8]) -> bool, data: &[u8]) -> (bool, f64, usize) {
    let start = Instant::now();
    let mut accepted = false;
    let peak = counting::peak_during(|| accepted = entry(data));
    assert!(
        peak <= allocation_bound(data.len()),
        "a {}-byte input held {peak} bytes at once",
        data.len()
    );
    (accepted, start.elapsed().as_secs_f64(), peak)
}

/// One change to a seed.
#[derive(Debug, Clone)]
enum Edit {
    Set(usize, u8),
    Flip(usize, u8),
    Truncate(usize),
    Insert(usize, Vec<u8>),
    Remove(usize, usize),
    /// A big-endian word from [`WORDS`] (sizes, lengths, counts).
    Word(usize, usize),
}

/// Values that break size arithmetic.
const WORDS: [u32; 10] = [
    0,
    1,
    0xFFFF,
    0x1_0000,
    8193,
    0x7FFF_FFFF,
    0x8000_0000,
    0xFFFF_FFFF,
    16_777_216,
    2048,
];

/// A position: half the time within the first 64 bytes (headers), else anywhere.
fn position() -> impl Strategy<Value = usize> {
    prop_oneof![0usize..64, any::<usize>()]
}

fn edit() -> impl Strategy<Value = Edit> {
    prop_oneof![
        (position(), any::<u8>()).prop_map(|(i, b)| Edit::Set(i, b)),
        (position(), 0u8..8).prop_map(|(i, bit)| Edit::Flip(i, 1 << bit)),
        any::<usize>().prop_map(Edit::Truncate),
        (position(), prop::collection::vec(any::<u8>(), 1..16))
            .prop_map(|(i, b)| Edit::Insert(i, b)),
        (position(), 1usize..64).prop_map(|(i, n)| Edit::Remove(i, n)),
        (position(), 0..WORDS.len()).prop_map(|(i, w)| Edit::Word(i, w)),
    ]
}

fn apply(mut v: Vec<u8>, edits: &[Edit]) -> Vec<u8> {
    for e in edits {
        let at = |i: usize, v: &Vec<u8>| if v.is_empty() { 0 } else { i % v.len() };
        match e {
            Edit::Set(i, b) if !v.is_empty() => {
                let i = at(*i, &v);
                v[i] = *b;
            }
            Edit::Flip(i, m) if !v.is_empty() => {
                let i = at(*i, &v);
                v[i] ^= m;
            }
            Edit::Truncate(i) => v.truncate(i % (v.len() + 1)),
            Edit::Insert(i, b) => {
                let i = i % (v.len() + 1);
                v.splice(i..i, b.iter().copied());
            }
            Edit::Remove(i, n) if !v.is_empty() => {
                let i = at(*i, &v);
                v.drain(i..(i + n).min(v.len()));
            }
            Edit::Word(i, w) if v.len() >= 4 => {
                let i = i % (v.len() - 3);
                v[i..i + 4].copy_from_slice(&WORDS[*w].to_be_bytes());
            }
            _ => {}
        }
    }
    v
}

/// Rewrites the CRC of every whole chunk of a PNG, so that a change reaches the decoder instead
/// of stopping at the checksum.
fn fix_png_crcs(v: &mut [u8]) {
    let mut at = 8;
    while at + 12 <= v.len() {
        let len = u32::from_be_bytes([v[at], v[at + 1], v[at + 2], v[at + 3]]) as usize;
        let Some(end) = (at + 8).checked_add(len).filter(|&e| e + 4 <= v.len()) else {
            return;
        };
        let crc = crc32fast::hash(&v[at + 4..end]);
        v[end..end + 4].copy_from_slice(&crc.to_be_bytes());
        at = end + 4;
    }
}

/// Seeds, mutated (PNG chunks' CRCs then fixed), or arbitrary bytes.
fn inputs(seeds: Vec<Vec<u8>>) -> impl Strategy<Value = Vec<u8>> {
    let seeds = Arc::new(seeds);
    let n = seeds.len();
    let mutated = (0..n, prop::collection::vec(edit(), 0..6), any::<bool>()).prop_map(
        move |(i, edits, keep_crcs)| {
            let mut v = apply(seeds[i].clone(), &edits);
            if !keep_crcs && v.starts_with(b"\x89PNG") {
                fix_png_crcs(&mut v);
            }
            v
        },
    );
    prop_oneof![
        4 => mutated,
        1 => prop::collection::vec(any::<u8>(), 0..512),
    ]
}

fn shared(rel: &str) -> Option<Vec<u8>> {
    std::fs::read(
        Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("../../../shared/data/real-rgbd")
            .join(rel),
    )
    .ok()
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
fn small_depth(w: u32, h: u32) -> Vec<u8> {
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

fn small_pngs() -> Vec<Vec<u8>> {
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

fn jpegs() -> Vec<Vec<u8>> {
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

fn npys() -> Vec<Vec<u8>> {
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

fn camera_json() -> Vec<u8> {
    br#"{"fx": 520.9, "fy": 521.0, "cx": 325.1, "cy": 249.7, "width": 17, "height": 11, "depth_scale": 1000.0, "pitch_deg": 10.0, "height_m": 0.5, "sensor": "kinect_v1"}"#.to_vec()
}

fn cameras() -> Vec<Vec<u8>> {
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

/// A multipart body of [`super::MULTIPART_TYPE`] with these parts.
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

fn multipart_bodies() -> Vec<Vec<u8>> {
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

fn client_message(msg: pb::client_message::Msg) -> Vec<u8> {
    pb::ClientMessage { msg: Some(msg) }.encode_to_vec()
}

fn stream_messages() -> Vec<Vec<u8>> {
    use pb::client_message::Msg;
    let frame = |image: Vec<u8>, depth: Vec<u8>, camera: Option<pb::Camera>| {
        client_message(Msg::Frame(pb::Frame {
            sequence: 7,
            timestamp_us: 1_700_000_000_000_000,
            image,
            depth,
            camera,
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

/// Any JSON value a camera key might be given.
fn json_value() -> impl Strategy<Value = serde_json::Value> {
    use serde_json::Value;
    prop_oneof![
        any::<f64>().prop_map(Value::from),
        prop_oneof![Just(0.0), Just(-1.0), Just(1e308), Just(500.0), Just(1e-9)]
            .prop_map(Value::from),
        any::<i64>().prop_map(Value::from),
        any::<u64>().prop_map(Value::from),
        ".{0,12}".prop_map(Value::from),
        any::<bool>().prop_map(Value::from),
        Just(Value::Null),
        prop::collection::vec(any::<f64>(), 0..4).prop_map(Value::from),
        Just(serde_json::json!({"sigma_mm": [1.0, 2.0]})),
    ]
}

/// A valid camera object with a few keys changed to any value (or unknown keys added) and a
/// few removed.
fn camera_objects() -> impl Strategy<Value = Vec<u8>> {
    let keys = super::super::request::CAMERA_KEYS.to_vec();
    let key = prop_oneof![
        8 => prop::sample::select(keys.clone()).prop_map(String::from),
        1 => "[a-z_]{1,10}",
    ];
    let changes = prop::collection::btree_map(key, json_value(), 0..4);
    let removals = prop::collection::vec(prop::sample::select(keys), 0..3);
    (changes, removals).prop_map(|(changes, removals)| {
        let serde_json::Value::Object(mut cam) =
            serde_json::from_slice(&camera_json()).expect("the seed camera is JSON; a bug")
        else {
            unreachable!("the seed camera is an object")
        };
        cam.extend(changes);
        for k in removals {
            cam.remove(k);
        }
        serde_json::to_vec(&cam).expect("a JSON value serialises; a bug")
    })
}

fn opt_f64() -> impl Strategy<Value = Option<f64>> {
    prop::option::of(prop_oneof![any::<f64>(), -200.0..200.0f64])
}

fn pb_cameras() -> impl Strategy<Value = Option<pb::Camera>> {
    let k = (
        any::<f64>(),
        0.0..2000.0f64,
        -100.0..1000.0f64,
        any::<f64>(),
    );
    let m = (opt_f64(), opt_f64(), opt_f64());
    let size = (prop::option::of(any::<u32>()), prop::option::of(0u32..100));
    let sensor = (
        prop::option::of("[a-z_0-9]{0,12}"),
        prop::collection::vec(any::<f64>(), 0..5),
    );
    prop::option::of((k, m, size, sensor).prop_map(
        |((fx, fy, cx, cy), (pitch_deg, height_m, depth_scale), (width, height), (name, sigma))| {
            pb::Camera {
                fx,
                fy,
                cx,
                cy,
                pitch_deg,
                height_m,
                depth_scale,
                width,
                height,
                sensor: name,
                sensor_sigma_mm: sigma,
            }
        },
    ))
}

/// Hellos and frames built field by field, with any values.
fn stream_structured() -> impl Strategy<Value = Vec<u8>> {
    use pb::client_message::Msg;
    let hello = (
        pb_cameras(),
        (any::<i32>(), any::<i32>(), any::<i32>(), any::<u32>()),
        (opt_f64(), opt_f64(), opt_f64()),
        any::<(bool, bool, bool)>(),
    )
        .prop_map(
            |(camera, (mode, format, normals, dsac_hypotheses), (preview, r, s), (a, b, c))| {
                client_message(Msg::Hello(pb::Hello {
                    camera,
                    mode,
                    format,
                    seed: 3,
                    preview_max_m: preview,
                    want_traversable: a,
                    normals,
                    dsac_hypotheses,
                    max_roughness_cm: r,
                    max_slope_deg: s,
                    want_traversal: b,
                    want_uncertainty: c,
                }))
            },
        );
    let images = Arc::new(small_pngs());
    let frame = (pb_cameras(), 0..3usize, 0..3usize).prop_map(move |(camera, i, d)| {
        let pick = |k: usize| match k {
            0 => Vec::new(),
            1 => images[0].clone(),
            _ => images[4].clone(),
        };
        client_message(Msg::Frame(pb::Frame {
            sequence: 9,
            timestamp_us: -1,
            image: pick(i),
            depth: pick(d),
            camera,
        }))
    });
    prop_oneof![hello, frame]
}

/// Statistics of one run: cases, accepted, slowest case (s), largest peak (bytes).
#[derive(Debug, Clone, Copy, Default)]
struct Stats {
    cases: u32,
    accepted: u32,
    slowest_s: f64,
    peak: usize,
}

/// Runs `cases` cases (times `TRE_FUZZ_SCALE`) of `strategy` through `entry`, printing their
/// count, how many were accepted, time and peak. Some must be accepted and some refused, or the
/// mutations miss the decoders' far ends or their error paths.
fn fuzz(
    name: &str,
    cases: u32,
    strategy: impl Strategy<Value = Vec<u8>>,
    entry: fn(&[u8]) -> bool,
) {
    use proptest::test_runner::{Config, TestRunner};
    let scale: u32 = std::env::var("TRE_FUZZ_SCALE")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(1);
    let start = Instant::now();
    let stats = std::cell::Cell::new(Stats::default());
    let mut runner = TestRunner::new(Config {
        cases: cases.saturating_mul(scale.max(1)),
        // A failure prints its smallest input; these runs keep no regression files.
        failure_persistence: None,
        ..Config::default()
    });
    let result = runner.run(&strategy, |data| {
        let (accepted, took, peak) = run_case(entry, &data);
        let s = stats.get();
        stats.set(Stats {
            cases: s.cases + 1,
            accepted: s.accepted + u32::from(accepted),
            slowest_s: s.slowest_s.max(took),
            peak: s.peak.max(peak),
        });
        Ok(())
    });
    if let Err(e) = result {
        panic!("{name}: {e}");
    }
    let s = stats.get();
    eprintln!(
        "fuzz {name}: {} cases ({} accepted) in {:.2} s, slowest {:.1} ms, peak {:.1} MB",
        s.cases,
        s.accepted,
        start.elapsed().as_secs_f64(),
        s.slowest_s * 1e3,
        s.peak as f64 / 1e6
    );
    assert!(
        s.accepted > 0 && s.accepted < s.cases,
        "{name}: {} of {} accepted",
        s.accepted,
        s.cases
    );
}

#[test]
fn fuzz_images() {
    let mut seeds = small_pngs();
    seeds.extend(jpegs());
    seeds.extend(real_frames());
    fuzz("image", 3000, inputs(seeds), super::image);
}

#[test]
fn fuzz_depth() {
    let mut seeds = small_pngs();
    seeds.extend(npys());
    seeds.extend(real_frames());
    fuzz("depth", 3000, inputs(seeds), super::depth);
}

#[test]
fn fuzz_npy() {
    fuzz("npy", 5000, inputs(npys()), super::npy);
}

#[test]
fn fuzz_camera_json() {
    fuzz("camera bytes", 5000, inputs(cameras()), super::camera);
    fuzz("camera objects", 5000, camera_objects(), super::camera);
}

#[test]
fn fuzz_multipart() {
    fuzz(
        "multipart",
        2000,
        inputs(multipart_bodies()),
        super::multipart,
    );
}

#[test]
fn fuzz_stream_messages() {
    fuzz(
        "stream bytes",
        3000,
        inputs(stream_messages()),
        super::stream,
    );
    fuzz("stream fields", 5000, stream_structured(), super::stream);
}

/// The seeds themselves pass: the entry points accept well-formed input, so the mutations
/// start from inputs that reach the decoders' far ends.
#[test]
fn seeds_are_accepted() {
    for png in small_pngs() {
        assert!(super::decode_image("rgb", &png, super::limits()).is_ok());
    }
    assert!(super::decode_depth(&small_depth(17, 11), 1000.0, super::limits()).is_ok());
    assert!(super::strict_camera(&camera_json(), super::limits()).is_ok());
    let runtime = tokio::runtime::Builder::new_current_thread()
        .build()
        .unwrap();
    for body in multipart_bodies() {
        let req = runtime
            .block_on(super::parse_body(
                super::MULTIPART_TYPE,
                body.into(),
                super::limits(),
            ))
            .unwrap();
        super::decode_frame(&req, super::limits()).unwrap();
    }
    for msg in stream_messages() {
        assert!(super::decode_client(&msg).is_ok());
    }
}
