//! The server's memory over a sustained stream, which `cargo test` leaves out for its length
//! (about five minutes in the test profile on two cores, longer than the rest of the suite
//! together): `tre serve` with one worker answers small frames (64×48, the rgb mode, so every
//! net and DSAC run) one at a time on one stream; its RSS after `TRE_STREAM_FRAMES` frames
//! (default 1000) must be within 16 MiB of its RSS after the first 200 (the warm-up).
//!
//! `cargo bench --bench stream_memory` prints both and exits with status 1 when the RSS grew
//! more. The ten-minute soak of real depth frames at 15 frames/s is `scripts/soak_stream.sh`
//! (docs/benchmarks.md).
#![allow(missing_docs, clippy::unwrap_used)]

#[path = "../tests/it/common/mod.rs"]
mod common;

use common::stream::{connect, frame, handshake, next, rt, send, Ws};
use common::Server;
use tre::proto::v1 as pb;

/// Sends frames `from..to` one at a time, each answered before the next.
async fn run(ws: &mut Ws, image: &[u8], from: u64, to: u64) {
    for sequence in from..to {
        send(ws, frame(sequence, image.to_vec())).await;
        match next(ws).await {
            pb::server_message::Msg::Result(r) => assert_eq!(r.sequence, sequence),
            other => panic!("frame {sequence}: {other:?}"),
        }
    }
}

fn main() -> std::process::ExitCode {
    let server = Server::start(&["--workers", "1"]);
    let image = common::pattern_png(64, 48);
    let frames: u64 = std::env::var("TRE_STREAM_FRAMES")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(1000);
    let (before, after) = rt().block_on(async {
        let mut ws = connect(&server).await;
        handshake(&mut ws, pb::Format::Png16, pb::Mode::Rgb).await;
        run(&mut ws, &image, 0, 200).await;
        let before = server.rss_kib();
        run(&mut ws, &image, 200, 200 + frames).await;
        (before, server.rss_kib())
    });
    let grew = after as i64 - before as i64;
    println!(
        "RSS over {frames} frames of 64×48 in rgb mode: {before} KiB after the warm-up, {after} \
         KiB after ({grew:+} KiB; bound +16384 KiB)"
    );
    if after < before + 16 * 1024 {
        std::process::ExitCode::SUCCESS
    } else {
        println!("over the bound: the server's memory grows with the frames it answers");
        std::process::ExitCode::FAILURE
    }
}
