//! Shutdown closes streams cleanly after answering what they sent; memory stays flat over a
//! sustained stream.

use super::*;

#[test]
fn shutdown_closes_streams_cleanly() {
    crate::common::skip_unless_shared!("data/real-rgbd");
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
    crate::common::skip_unless_shared!("data/real-rgbd");
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
