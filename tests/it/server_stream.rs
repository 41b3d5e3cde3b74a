//! `GET /v1/stream` on a real `tre serve` over loopback: results equal `tre infer`, latest
//! frame wins with drops reported, garbage and oversize messages are errors that keep the
//! stream open, vanishing clients do not hurt the server, and memory stays flat over thousands
//! of frames.
#![allow(clippy::unwrap_used)] // Test helpers fail loudly by design.

use crate::common;

use std::time::Duration;

use common::{get, infer_png16, png16_values, real, Server};
use futures_util::{SinkExt, StreamExt};
use prost::Message as _;
use tokio_tungstenite::tungstenite::Message;
use tre::proto::v1 as pb;

type Ws =
    tokio_tungstenite::WebSocketStream<tokio_tungstenite::MaybeTlsStream<tokio::net::TcpStream>>;

fn rt() -> tokio::runtime::Runtime {
    tokio::runtime::Builder::new_multi_thread()
        .enable_all()
        .build()
        .unwrap()
}

async fn connect(server: &Server) -> Ws {
    let url = format!("ws://{}/v1/stream", server.addr);
    tokio_tungstenite::connect_async(url).await.unwrap().0
}

fn hello(format: pb::Format, mode: pb::Mode) -> Vec<u8> {
    pb::ClientMessage {
        msg: Some(pb::client_message::Msg::Hello(pb::Hello {
            format: format as i32,
            mode: mode as i32,
            ..Default::default()
        })),
    }
    .encode_to_vec()
}

fn frame(sequence: u64, image: Vec<u8>) -> Vec<u8> {
    pb::ClientMessage {
        msg: Some(pb::client_message::Msg::Frame(pb::Frame {
            sequence,
            timestamp_us: 1_000 + sequence as i64,
            image,
            ..Default::default()
        })),
    }
    .encode_to_vec()
}

async fn send(ws: &mut Ws, bytes: Vec<u8>) {
    ws.send(Message::Binary(bytes.into())).await.unwrap();
}

/// The next server message (pings skipped).
async fn next(ws: &mut Ws) -> pb::server_message::Msg {
    loop {
        let msg = tokio::time::timeout(Duration::from_secs(60), ws.next())
            .await
            .expect("no message within 60 s")
            .expect("stream ended")
            .expect("stream failed");
        match msg {
            Message::Binary(b) => return pb::ServerMessage::decode(&b[..]).unwrap().msg.unwrap(),
            Message::Ping(_) | Message::Pong(_) => continue,
            other => panic!("unexpected {other:?}"),
        }
    }
}

async fn handshake(ws: &mut Ws, format: pb::Format, mode: pb::Mode) {
    send(ws, hello(format, mode)).await;
    match next(ws).await {
        pb::server_message::Msg::Ready(r) => assert!(r.models.iter().any(|m| m == "depth_net")),
        other => panic!("expected Ready, got {other:?}"),
    }
}

#[test]
fn the_hello_sets_the_traversability_thresholds() {
    let server = Server::start(&["--workers", "1"]);
    let image = std::fs::read(real("slambook2_ch7/2.png")).unwrap();
    let hello_with = |max_roughness_cm, max_slope_deg| {
        pb::ClientMessage {
            msg: Some(pb::client_message::Msg::Hello(pb::Hello {
                mode: pb::Mode::Rgb as i32,
                format: pb::Format::F32 as i32,
                want_traversable: true,
                max_roughness_cm,
                max_slope_deg,
                ..Default::default()
            })),
        }
        .encode_to_vec()
    };
    rt().block_on(async {
        // (traversable pixels, pixels with roughness) under each pair of thresholds.
        let mut counts = Vec::new();
        for (sequence, (cm, deg)) in [
            (None, None),
            (Some(1e4), Some(90.0)),
            (Some(1e-4), Some(0.0)),
        ]
        .into_iter()
        .enumerate()
        {
            let mut ws = connect(&server).await;
            send(&mut ws, hello_with(cm, deg)).await;
            assert!(matches!(
                next(&mut ws).await,
                pb::server_message::Msg::Ready(_)
            ));
            send(&mut ws, frame(sequence as u64 + 1, image.clone())).await;
            let pb::server_message::Msg::Result(r) = next(&mut ws).await else {
                panic!("expected a Result");
            };
            let valid = r
                .roughness
                .chunks_exact(4)
                .filter(|b| f32::from_le_bytes([b[0], b[1], b[2], b[3]]).is_finite())
                .count();
            let traversable = r.traversable.iter().filter(|&&t| t == 1).count();
            counts.push((traversable, valid));
            ws.close(None).await.unwrap();
        }
        let (default, loose, strict) = (counts[0], counts[1], counts[2]);
        assert!(
            default.1 > 0 && default.1 == loose.1 && loose.1 == strict.1,
            "{counts:?}"
        );
        assert_eq!(
            loose.0, loose.1,
            "every pixel with roughness passes 100 m and 90°"
        );
        assert_eq!(strict.0, 0, "none passes 1 µm and 0°");
        assert!(0 < default.0 && default.0 < default.1, "{counts:?}");

        let mut ws = connect(&server).await;
        send(&mut ws, hello_with(None, Some(95.0))).await;
        match next(&mut ws).await {
            pb::server_message::Msg::Error(e) => {
                assert_eq!(e.code, "bad_request");
                assert!(e.message.contains("hello.max_slope_deg"), "{}", e.message);
            }
            other => panic!("expected an Error, got {other:?}"),
        }
    });
}

#[test]
fn the_hello_chooses_dsac_hypotheses_and_a_bad_number_is_an_error() {
    let server = Server::start(&["--workers", "1"]);
    let path = real("slambook2_ch7/2.png");
    let four = infer_png16(&[
        path.to_str().unwrap(),
        "--mode",
        "rgb",
        "--dsac-hypotheses",
        "4",
    ]);
    let hello_with = |dsac_hypotheses| {
        pb::ClientMessage {
            msg: Some(pb::client_message::Msg::Hello(pb::Hello {
                mode: pb::Mode::Rgb as i32,
                dsac_hypotheses,
                ..Default::default()
            })),
        }
        .encode_to_vec()
    };
    rt().block_on(async {
        let mut ws = connect(&server).await;
        send(&mut ws, hello_with(65)).await;
        match next(&mut ws).await {
            pb::server_message::Msg::Error(e) => {
                assert_eq!(e.code, "bad_request");
                assert!(e.message.contains("hello.dsac_hypotheses"), "{}", e.message);
                assert!(e.message.contains("1 to 64"), "{}", e.message);
            }
            other => panic!("expected an Error, got {other:?}"),
        }
        send(&mut ws, hello_with(4)).await;
        assert!(matches!(
            next(&mut ws).await,
            pb::server_message::Msg::Ready(_)
        ));
        send(&mut ws, frame(1, std::fs::read(&path).unwrap())).await;
        match next(&mut ws).await {
            pb::server_message::Msg::Result(r) => {
                assert_eq!(png16_values(&r.roughness), four, "K = 4 over the stream");
            }
            other => panic!("expected a Result, got {other:?}"),
        }
        ws.close(None).await.unwrap();
    });
}

#[test]
fn stream_results_equal_tre_infer() {
    let server = Server::start(&["--workers", "1"]);
    let path = real("slambook2_ch7/2.png");
    let reference = infer_png16(&[path.to_str().unwrap(), "--mode", "rgb"]);
    rt().block_on(async {
        let mut ws = connect(&server).await;
        handshake(&mut ws, pb::Format::Png16, pb::Mode::Rgb).await;
        let image = std::fs::read(&path).unwrap();
        for seq in [7u64, 8, 9] {
            send(&mut ws, frame(seq, image.clone())).await;
            match next(&mut ws).await {
                pb::server_message::Msg::Result(r) => {
                    assert_eq!(r.sequence, seq);
                    assert_eq!(r.timestamp_us, 1_000 + seq as i64);
                    assert_eq!((r.width, r.height), (640, 480));
                    assert_eq!(r.scale_m, 1e-4);
                    assert!(r.timings.iter().any(|t| t.stage == "normals" && t.ms > 0.0));
                    assert!(r.latency_ms > 0.0);
                    assert_eq!(png16_values(&r.roughness), reference, "frame {seq}");
                }
                other => panic!("expected a Result, got {other:?}"),
            }
        }
        ws.close(None).await.unwrap();
    });
}

#[test]
fn latest_frame_wins_and_drops_are_reported() {
    let server = Server::start(&["--workers", "1"]);
    let image = std::fs::read(real("slambook2_ch7/1.png")).unwrap();
    rt().block_on(async {
        let mut ws = connect(&server).await;
        handshake(&mut ws, pb::Format::F32, pb::Mode::Rgb).await;
        for seq in 0..6 {
            send(&mut ws, frame(seq, image.clone())).await;
        }
        let (mut results, mut dropped, mut last_total) = (Vec::new(), Vec::new(), 0);
        while results.len() + dropped.len() < 6 {
            match next(&mut ws).await {
                pb::server_message::Msg::Result(r) => {
                    assert_eq!(r.roughness.len(), 640 * 480 * 4);
                    last_total = last_total.max(r.dropped_total);
                    results.push(r.sequence);
                }
                pb::server_message::Msg::Dropped(d) => {
                    assert_eq!(d.dropped_total, dropped.len() as u64 + 1);
                    dropped.push(d.sequence);
                }
                other => panic!("unexpected {other:?}"),
            }
        }
        // Frames sent back to back while one runs: the first and the newest are processed, the
        // ones in between are dropped, each once, and no frame is lost without a word.
        assert_eq!(results.first(), Some(&0));
        assert_eq!(results.last(), Some(&5));
        assert!(!dropped.is_empty(), "nothing was dropped");
        let mut all: Vec<u64> = results.iter().chain(&dropped).copied().collect();
        all.sort_unstable();
        assert_eq!(all, (0..6).collect::<Vec<_>>());
        assert_eq!(last_total, dropped.len() as u64);
    });
    let metrics = String::from_utf8(get(server.addr, "/metrics").1).unwrap();
    assert!(!metrics.contains("tre_frames_dropped_total 0"));
}

#[test]
fn bad_messages_are_errors_and_the_stream_goes_on() {
    let mut server = Server::start(&["--workers", "1", "--ws-max-message-bytes", "1000000"]);
    let small = common::pattern_png(64, 48);
    rt().block_on(async {
        let mut ws = connect(&server).await;
        // A frame before the Hello.
        send(&mut ws, frame(1, small.clone())).await;
        let expect_error = |m: pb::server_message::Msg, code: &str| match m {
            pb::server_message::Msg::Error(e) => {
                assert_eq!(e.code, code, "{}", e.message);
                assert!(!e.message.is_empty());
                e
            }
            other => panic!("expected error {code}, got {other:?}"),
        };
        let e = expect_error(next(&mut ws).await, "bad_request");
        assert_eq!(e.sequence, Some(1));
        handshake(&mut ws, pb::Format::Png16, pb::Mode::Rgb).await;
        send(&mut ws, vec![0xFF, 0x13, 0x37, 0x00, 0xAB]).await;
        expect_error(next(&mut ws).await, "bad_request");
        ws.send(Message::Text("hello?".into())).await.unwrap();
        expect_error(next(&mut ws).await, "bad_request");
        send(&mut ws, frame(2, b"not an image at all".to_vec())).await;
        let e = expect_error(next(&mut ws).await, "unsupported_media");
        assert_eq!(e.sequence, Some(2));
        let truncated = std::fs::read(real("slambook2_ch7/1.png")).unwrap()[..4000].to_vec();
        send(&mut ws, frame(3, truncated)).await;
        expect_error(next(&mut ws).await, "bad_image");
        send(&mut ws, frame(4, common::png_with_header(90_000, 90_000))).await;
        expect_error(next(&mut ws).await, "too_large");
        send(&mut ws, frame(5, vec![0x89; 1_500_000])).await;
        // Over the message limit, it is not decoded, yet its error names the frame.
        let e = expect_error(next(&mut ws).await, "too_large");
        assert_eq!(e.sequence, Some(5));
        let bad_cam = pb::ClientMessage {
            msg: Some(pb::client_message::Msg::Frame(pb::Frame {
                sequence: 6,
                image: small.clone(),
                camera: Some(pb::Camera {
                    fx: f64::NAN,
                    fy: 1.0,
                    cx: 0.0,
                    cy: 0.0,
                    ..Default::default()
                }),
                ..Default::default()
            })),
        };
        send(&mut ws, bad_cam.encode_to_vec()).await;
        expect_error(next(&mut ws).await, "bad_camera");
        // Intrinsics stated for 640×480 with a 64×48 frame would misplace every point.
        let other_size = pb::ClientMessage {
            msg: Some(pb::client_message::Msg::Frame(pb::Frame {
                sequence: 7,
                image: small.clone(),
                camera: Some(pb::Camera {
                    fx: 525.0,
                    fy: 525.0,
                    cx: 32.0,
                    cy: 24.0,
                    width: Some(640),
                    height: Some(480),
                    ..Default::default()
                }),
                ..Default::default()
            })),
        };
        send(&mut ws, other_size.encode_to_vec()).await;
        let e = expect_error(next(&mut ws).await, "bad_camera");
        assert_eq!(e.sequence, Some(7));
        assert!(e.message.contains("640×480"), "{}", e.message);
        // After all that, the same stream still answers a good frame.
        send(&mut ws, frame(10, small.clone())).await;
        match next(&mut ws).await {
            pb::server_message::Msg::Result(r) => {
                assert_eq!((r.sequence, r.width, r.height), (10, 64, 48))
            }
            other => panic!("expected a Result, got {other:?}"),
        }
        // Beyond 4× the limit the connection is closed (1009), and the server is unharmed.
        let _ = ws.send(Message::Binary(vec![0u8; 4_500_000].into())).await;
        let closed = tokio::time::timeout(Duration::from_secs(30), async {
            loop {
                match ws.next().await {
                    Some(Ok(Message::Close(f))) => break f.map(|f| u16::from(f.code)),
                    Some(Ok(_)) => continue,
                    _ => break None,
                }
            }
        })
        .await
        .unwrap();
        assert!(
            closed.is_none() || closed == Some(1009),
            "closed with {closed:?}"
        );

        // Clients that vanish mid-stream, with a frame in flight.
        for _ in 0..3 {
            let mut ws = connect(&server).await;
            handshake(&mut ws, pb::Format::Png16, pb::Mode::Rgb).await;
            send(&mut ws, frame(1, small.clone())).await;
            drop(ws);
        }
        let mut ws = connect(&server).await;
        handshake(&mut ws, pb::Format::Png16, pb::Mode::Rgb).await;
        // Their frames may still hold queue slots (a worker skips each one as it comes to it),
        // so the next client may be told `overloaded` for a moment, and then is served.
        let mut answered = false;
        for attempt in 0..50 {
            send(&mut ws, frame(11 + attempt, small.clone())).await;
            match next(&mut ws).await {
                pb::server_message::Msg::Result(r) => {
                    assert_eq!(r.sequence, 11 + attempt);
                    answered = true;
                    break;
                }
                pb::server_message::Msg::Error(e) if e.code == "overloaded" => {
                    tokio::time::sleep(Duration::from_millis(100)).await;
                }
                other => panic!("unexpected {other:?}"),
            }
        }
        assert!(
            answered,
            "the server did not serve a new client after the vanished ones"
        );
    });
    assert!(server.alive());
}

#[test]
fn shutdown_closes_streams_cleanly() {
    let server = Server::start(&["--workers", "1"]);
    let image = std::fs::read(real("slambook2_ch7/1.png")).unwrap();
    let rt = rt();
    let mut ws = rt.block_on(async {
        let mut ws = connect(&server).await;
        handshake(&mut ws, pb::Format::Png16, pb::Mode::Rgb).await;
        send(&mut ws, frame(1, image)).await;
        ws
    });
    std::thread::sleep(Duration::from_millis(20));
    let status = server.terminate();
    assert!(status.success(), "{status}");
    rt.block_on(async {
        let mut got_result = false;
        let mut close = None;
        while let Some(Ok(m)) = ws.next().await {
            match m {
                Message::Binary(b) => {
                    if let Some(pb::server_message::Msg::Result(r)) =
                        pb::ServerMessage::decode(&b[..]).unwrap().msg
                    {
                        got_result = r.sequence == 1;
                    }
                }
                Message::Close(f) => {
                    close = f.map(|f| u16::from(f.code));
                    break;
                }
                _ => {}
            }
        }
        assert!(
            got_result,
            "the frame in flight was not answered before the close"
        );
        assert_eq!(close, Some(1001));
    });
}

/// Two small frames back to back, then SIGTERM at once or a little later: whatever the timing,
/// the stream ends with the 1001 close, not a reset, and no frame is answered twice; frames
/// the server had read are answered (a result, or dropped if still waiting). The server once
/// exited as soon as its HTTP side was done, and closed with frames unread, cutting streams
/// off mid-answer.
#[test]
fn shutdown_ends_a_stream_with_a_close_after_answering_what_it_read() {
    let small = {
        let img = image::open(real("slambook2_ch7/1.png"))
            .unwrap()
            .thumbnail(32, 24);
        let mut out = Vec::new();
        img.write_to(&mut std::io::Cursor::new(&mut out), image::ImageFormat::Png)
            .unwrap();
        out
    };
    for delay_ms in [0, 10, 300] {
        let server = Server::start(&["--workers", "1"]);
        let rt = rt();
        let mut ws = rt.block_on(async {
            let mut ws = connect(&server).await;
            handshake(&mut ws, pb::Format::Png16, pb::Mode::Rgb).await;
            send(&mut ws, frame(1, small.clone())).await;
            send(&mut ws, frame(2, small.clone())).await;
            ws
        });
        std::thread::sleep(Duration::from_millis(delay_ms));
        let status = server.terminate();
        assert!(status.success(), "{status}");
        rt.block_on(async {
            let (mut answered, mut close) = (Vec::new(), None);
            while let Some(m) = ws.next().await {
                match m.unwrap_or_else(|e| panic!("after {delay_ms} ms: {e}, not a close")) {
                    Message::Binary(b) => match pb::ServerMessage::decode(&b[..]).unwrap().msg {
                        Some(pb::server_message::Msg::Result(r)) => answered.push(r.sequence),
                        Some(pb::server_message::Msg::Dropped(d)) => answered.push(d.sequence),
                        other => panic!("unexpected {other:?}"),
                    },
                    Message::Close(f) => {
                        close = f.map(|f| u16::from(f.code));
                        break;
                    }
                    _ => {}
                }
            }
            answered.sort_unstable();
            assert_eq!(close, Some(1001), "after {delay_ms} ms");
            assert!(
                [&[][..], &[1], &[1, 2]].contains(&&answered[..]),
                "after {delay_ms} ms: {answered:?}"
            );
            if delay_ms >= 300 {
                // Both had long arrived: both are answered.
                assert_eq!(answered, [1, 2], "after {delay_ms} ms");
            }
        });
    }
}

/// Streams thousands of small frames and reports the server's RSS before and after; it must
/// stay flat (growth under 16 MiB once warm).
#[test]
fn memory_stays_flat_over_a_sustained_stream() {
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
    eprintln!("RSS over {frames} frames of 64×48 in rgb mode: {before} KiB before, {after} KiB after ({:+} KiB)", after as i64 - before as i64);
    assert!(
        after < before + 16 * 1024,
        "RSS grew from {before} KiB to {after} KiB"
    );
}

/// Sends frames `from..to` one at a time, each answered before the next.
async fn run(ws: &mut Ws, image: &[u8], from: u64, to: u64) {
    for seq in from..to {
        send(ws, frame(seq, image.to_vec())).await;
        match next(ws).await {
            pb::server_message::Msg::Result(r) => assert_eq!(r.sequence, seq),
            other => panic!("frame {seq}: {other:?}"),
        }
    }
}

#[test]
fn streams_over_the_limit_are_refused_at_once() {
    let server = Server::start(&["--workers", "1", "--max-streams", "1"]);
    rt().block_on(async {
        let mut first = connect(&server).await;
        handshake(&mut first, pb::Format::Png16, pb::Mode::Rgb).await;
        let url = format!("ws://{}/v1/stream", server.addr);
        match tokio_tungstenite::connect_async(url.clone()).await {
            Err(tokio_tungstenite::tungstenite::Error::Http(resp)) => {
                assert_eq!(resp.status().as_u16(), 429);
                assert_eq!(resp.headers()["retry-after"], "1");
                let body: serde_json::Value =
                    serde_json::from_slice(resp.body().as_deref().unwrap()).unwrap();
                assert_eq!(body["error"]["code"], "too_many_requests");
            }
            other => panic!("expected a 429, got {:?}", other.map(|_| ())),
        }
        // Once the first stream closes, a new one is accepted.
        first.close(None).await.unwrap();
        while first.next().await.is_some() {}
        let mut accepted = None;
        for _ in 0..50 {
            if let Ok((ws, _)) = tokio_tungstenite::connect_async(url.clone()).await {
                accepted = Some(ws);
                break;
            }
            tokio::time::sleep(Duration::from_millis(50)).await;
        }
        handshake(
            accepted
                .as_mut()
                .expect("no stream accepted after the first closed"),
            pb::Format::Png16,
            pb::Mode::Rgb,
        )
        .await;
    });
}

/// A client that stops reading, such as a hung robot process with its socket still open, once
/// held its stream (and a `--max-streams` place) for good, and the server's shutdown for the
/// whole grace time: the server waited forever to send it an answer, and did not ping it or
/// read from it meanwhile. Now an answer it takes nothing of within `--stall-timeout-ms` ends
/// its stream, which frees the place.
#[test]
fn a_client_that_stops_reading_is_dropped_after_the_stall_timeout() {
    let server = Server::start(&[
        "--workers",
        "1",
        "--max-streams",
        "1",
        "--stall-timeout-ms",
        "1500",
    ]);
    let image = std::fs::read(real("slambook2_ch7/1.png")).unwrap();
    let url = format!("ws://{}/v1/stream", server.addr);
    rt().block_on(async {
        // A small receive buffer, so that the answers (640×480 float maps, 1.2 MB each) fill
        // the connection after a few frames.
        let socket = tokio::net::TcpSocket::new_v4().unwrap();
        socket.set_recv_buffer_size(4096).unwrap();
        let tcp = socket.connect(server.addr).await.unwrap();
        let plain = tokio_tungstenite::MaybeTlsStream::Plain(tcp);
        let (mut stuck, _) = tokio_tungstenite::client_async(url.clone(), plain)
            .await
            .unwrap();
        handshake(&mut stuck, pb::Format::F32, pb::Mode::Rgb).await;
        // Frames, one at a time and never reading an answer, until the server takes no more
        // (its answers are not taken, so it stops reading) or drops the connection.
        let mut sent = 0;
        for seq in 1..=200 {
            let msg = Message::Binary(frame(seq, image.clone()).into());
            match tokio::time::timeout(Duration::from_secs(3), stuck.send(msg)).await {
                Ok(Ok(())) => sent += 1,
                Ok(Err(_)) | Err(_) => break,
            }
            tokio::time::sleep(Duration::from_millis(150)).await;
        }
        assert!(sent < 200, "the server read every frame: nothing was stuck");
        // The stuck stream's place is freed: a new stream is accepted and answered.
        let mut accepted = None;
        for _ in 0..100 {
            if let Ok((ws, _)) = tokio_tungstenite::connect_async(url.clone()).await {
                accepted = Some(ws);
                break;
            }
            tokio::time::sleep(Duration::from_millis(100)).await;
        }
        let mut ws = accepted.expect("the stuck stream still holds the only place 10 s on");
        handshake(&mut ws, pb::Format::Png16, pb::Mode::Rgb).await;
        send(&mut ws, frame(1, common::pattern_png(64, 48))).await;
        match next(&mut ws).await {
            pb::server_message::Msg::Result(r) => assert_eq!(r.sequence, 1),
            other => panic!("expected a result, got {other:?}"),
        }
        drop(stuck);
    });
}

/// Opens a stream by hand on a raw socket (101 read), so that its bytes can be trickled.
fn raw_stream(server: &Server) -> std::net::TcpStream {
    use std::io::{Read, Write};
    let mut t = std::net::TcpStream::connect(server.addr).unwrap();
    let head = "GET /v1/stream HTTP/1.1\r\nHost: x\r\nUpgrade: websocket\r\nConnection: Upgrade\r\nSec-WebSocket-Key: dGhlIHNhbXBsZSBub25jZQ==\r\nSec-WebSocket-Version: 13\r\n\r\n";
    t.write_all(head.as_bytes()).unwrap();
    let mut answer = Vec::new();
    let mut byte = [0u8; 1];
    while !answer.ends_with(b"\r\n\r\n") {
        t.read_exact(&mut byte).unwrap();
        answer.push(byte[0]);
    }
    let answer = String::from_utf8_lossy(&answer);
    assert!(answer.starts_with("HTTP/1.1 101"), "{answer}");
    // A masked binary frame of 60000 bytes: its header and mask now, the payload never whole.
    t.write_all(&[0x82, 0xFE, 0xEA, 0x60, 1, 2, 3, 4]).unwrap();
    t
}

/// Eighty streams trickling a message at one byte a second (the defaults: 64 `--max-streams`
/// places) do not stop another client's stream: it is opened and its frame answered while they
/// trickle, since a stream takes its place with its first whole message; the trickling streams
/// are closed with 1008 at the end of their first whole `--min-body-rate` window (5 to 10 s).
#[test]
fn eighty_trickling_streams_do_not_starve_a_ready_stream() {
    use std::io::{Read, Write};
    use std::sync::atomic::{AtomicBool, Ordering};
    let server = Server::start(&["--workers", "1"]);
    let trickles: Vec<std::net::TcpStream> = (0..80).map(|_| raw_stream(&server)).collect();
    let trickle_start = std::time::Instant::now();
    let stop = std::sync::Arc::new(AtomicBool::new(false));
    let feeder = {
        let mut writers: Vec<std::net::TcpStream> =
            trickles.iter().map(|t| t.try_clone().unwrap()).collect();
        let stop = stop.clone();
        std::thread::spawn(move || {
            while !stop.load(Ordering::Relaxed) {
                for w in &mut writers {
                    let _ = w.write_all(b"x");
                }
                std::thread::sleep(Duration::from_secs(1));
            }
        })
    };
    std::thread::sleep(Duration::from_secs(1));
    let started = std::time::Instant::now();
    rt().block_on(async {
        let mut ws = connect(&server).await;
        handshake(&mut ws, pb::Format::Png16, pb::Mode::Rgb).await;
        send(&mut ws, frame(1, common::pattern_png(64, 48))).await;
        match next(&mut ws).await {
            pb::server_message::Msg::Result(r) => assert_eq!(r.sequence, 1),
            other => panic!("expected a result, got {other:?}"),
        }
    });
    assert!(
        started.elapsed() < Duration::from_secs(5),
        "a ready stream waited {:?} behind trickling ones",
        started.elapsed()
    );
    // The trickle stops before the first streams are judged (about 10 s in), so that no byte
    // meets a closed socket (whose reset could discard the answer before it is read).
    std::thread::sleep(Duration::from_secs(7).saturating_sub(trickle_start.elapsed()));
    stop.store(true, Ordering::Relaxed);
    feeder.join().unwrap();
    // Each trickling stream gets an error and a close with 1008 (0x03F0), then the end.
    for mut t in trickles.into_iter().take(3) {
        t.set_read_timeout(Some(Duration::from_secs(30))).unwrap();
        let mut got = Vec::new();
        let _ = t.read_to_end(&mut got);
        let close = got
            .windows(4)
            .any(|w| w == [0x88, w[1], 0x03, 0xF0] && w[1] >= 2);
        assert!(close, "no 1008 close in {} bytes: {got:?}", got.len());
        let text = String::from_utf8_lossy(&got);
        assert!(text.contains("--min-body-rate"), "{text}");
    }
}
