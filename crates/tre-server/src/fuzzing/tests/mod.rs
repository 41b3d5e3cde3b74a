//! Fuzzing on stable Rust: property tests that feed each entry point of [`super`] arbitrary bytes
//! and mutations of real inputs (the frames in `../shared/data/real-rgbd`, the JPEG fixtures,
//! small images, `.npy` files, cameras, multipart bodies and stream messages made here), and
//! bound what each case may allocate. The case counts keep the whole module to seconds;
//! `TRE_FUZZ_SCALE=N` runs N times as many, and the `cargo fuzz` targets in `fuzz/` are the
//! longer run. The inputs come from `seeds` (mutated by `mutate`) and `structured`; `counting`
//! measures what each case allocates.

mod counting;
mod mutate;
mod seeds;
mod structured;

use std::time::Instant;

use proptest::prelude::*;

use mutate::inputs;
use seeds::{
    camera_json, cameras, jpegs, multipart_bodies, npys, small_depth, small_pngs, stream_messages,
    with_images,
};
use structured::{camera_objects, stream_structured};

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
    let seeds = with_images(jpegs());
    fuzz("image", 3000, inputs(seeds), super::image);
}

#[test]
fn fuzz_depth() {
    let seeds = with_images(npys());
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
        assert!(super::decode_image(super::ImagePart::Rgb, &png, super::limits()).is_ok());
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
