//! Streams over the limit are refused at once; a client that stops reading is dropped; trickling
//! streams do not starve a ready one.

use super::*;

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
    crate::common::skip_unless_shared!("data/real-rgbd");
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
        crate::common::spawn_named("trickle-feeder", move || {
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
