//! Bad messages are errors and the stream goes on.

use super::*;

#[test]
fn bad_messages_are_errors_and_the_stream_goes_on() {
    crate::common::skip_unless_shared!("data/real-rgbd");
    let mut server = Server::start(&["--workers", "1", "--ws-max-message-bytes", "1000000"]);
    let small = common::pattern_png(64, 48);
    rt().block_on(async {
        let mut ws = connect(&server).await;
        // A frame before the Hello.
        send(&mut ws, frame(1, small.clone())).await;
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
        let bad_cam = pb::Camera {
            fx: f64::NAN,
            fy: 1.0,
            cx: 0.0,
            cy: 0.0,
            ..Default::default()
        };
        send(&mut ws, frame_with_camera(6, small.clone(), bad_cam)).await;
        expect_error(next(&mut ws).await, "bad_camera");
        // Intrinsics stated for 640×480 with a 64×48 frame would misplace every point.
        let other_size = pb::Camera {
            fx: 525.0,
            fy: 525.0,
            cx: 32.0,
            cy: 24.0,
            width: Some(640),
            height: Some(480),
            ..Default::default()
        };
        send(&mut ws, frame_with_camera(7, small.clone(), other_size)).await;
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
        oversize_message_closes_the_connection(ws).await;
        // Clients that vanish mid-stream, with a frame in flight.
        vanished_clients_leave_the_server_serving(&server, &small).await;
    });
    assert!(server.alive());
}

/// The error answer of a bad message, which must carry `code` and a message.
fn expect_error(m: pb::server_message::Msg, code: &str) -> pb::Error {
    match m {
        pb::server_message::Msg::Error(e) => {
            assert_eq!(e.code, code, "{}", e.message);
            assert!(!e.message.is_empty());
            e
        }
        other => panic!("expected error {code}, got {other:?}"),
    }
}

/// A frame message of `image` with its own camera.
fn frame_with_camera(sequence: u64, image: Vec<u8>, camera: pb::Camera) -> Vec<u8> {
    pb::ClientMessage {
        msg: Some(pb::client_message::Msg::Frame(pb::Frame {
            sequence,
            image,
            camera: Some(camera),
            ..Default::default()
        })),
    }
    .encode_to_vec()
}

/// A message beyond 4× `--ws-max-message-bytes`: the connection is closed (1009).
async fn oversize_message_closes_the_connection(mut ws: Ws) {
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
}

/// Clients that vanish mid-stream, with a frame in flight, leave the server serving a new one.
async fn vanished_clients_leave_the_server_serving(server: &Server, small: &[u8]) {
    let small = small.to_vec();
    for _ in 0..3 {
        let mut ws = connect(server).await;
        handshake(&mut ws, pb::Format::Png16, pb::Mode::Rgb).await;
        send(&mut ws, frame(1, small.clone())).await;
        drop(ws);
    }
    let mut ws = connect(server).await;
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
}
