//! A session whose server restarts, hangs or is at its connection limit reports it and
//! carries on.

use super::*;

#[test]
fn a_session_reconnects_to_a_restarted_server_and_carries_on() {
    crate::common::skip_unless_shared!("data/real-rgbd");
    let _serial = SERIAL
        .lock()
        .unwrap_or_else(std::sync::PoisonError::into_inner);
    let dir = tempfile::tempdir().unwrap();
    let frames = make_frames(&dir.path().join("frames"));
    let png = |i: usize| std::fs::read(&frames[i].1).unwrap();
    let addr = free_loopback_addr();
    let mut first = Server::start(&addr, &dir.path().join("first.log"));
    first.wait_ready();

    rt().block_on(async {
        let mut cfg = session_config(first.addr);
        cfg.reconnect.initial = Duration::from_millis(100);
        cfg.reconnect.max = Duration::from_millis(500);
        let (mut sender, mut events) = Session::connect(cfg).await.unwrap().split();
        assert_eq!(sender.send(Frame::rgb(png(0))).await.unwrap(), 1);
        match next(&mut events).await {
            Event::Result(r) => assert_eq!(r.sequence, 1),
            other => panic!("expected the first result, got {other:?}"),
        }

        // Frame 2 is in flight when the server dies.
        assert_eq!(sender.send(Frame::rgb(png(1))).await.unwrap(), 2);
        first.kill();
        assert!(matches!(
            next(&mut events).await,
            Event::Disconnected { .. }
        ));
        // Lost in flight, or (if the socket's end was seen before the frame left the client's
        // queue) lost for want of a connection: either way, reported and not awaited forever.
        match next(&mut events).await {
            Event::Lost {
                sequence: 2,
                reason: LostReason::Disconnected | LostReason::NotConnected,
            } => {}
            other => panic!("expected frame 2 lost, got {other:?}"),
        }

        // A new server on the same port; frame 3 waits for the reconnection.
        let second = Server::start(&addr, &dir.path().join("second.log"));
        assert_eq!(sender.send(Frame::rgb(png(2))).await.unwrap(), 3);
        expect_reconnected(&mut events).await;
        let expect_result = |ev: Event, seq: u64| match ev {
            Event::Result(r) => assert_eq!((r.sequence, r.dropped_total), (seq, 0)),
            other => panic!("expected result {seq}, got {other:?}"),
        };
        expect_result(next(&mut events).await, 3);
        assert_eq!(sender.send(Frame::rgb(png(3))).await.unwrap(), 4);
        expect_result(next(&mut events).await, 4);
        drop(sender);
        assert_eq!(
            events.recv().await,
            None,
            "the session ends once all is answered"
        );
        drop(second);
    });
}

/// `127.0.0.1:PORT` with a port that was free a moment ago.
fn free_loopback_addr() -> String {
    let port = TcpListener::bind("127.0.0.1:0")
        .unwrap()
        .local_addr()
        .unwrap()
        .port();
    format!("127.0.0.1:{port}")
}

/// The next event is `Reconnected`, after at least one attempt, to a server with the depth model.
async fn expect_reconnected(events: &mut tre::client::Events) {
    match next(events).await {
        Event::Reconnected {
            attempts, server, ..
        } => {
            assert!(attempts >= 1);
            assert!(server.models.iter().any(|m| m == "depth_net"));
        }
        other => panic!("expected Reconnected, got {other:?}"),
    }
}

/// 1200×1200 of noise: a 4.3 MB PNG, so that a few fill the socket buffers.
fn noise_png() -> Vec<u8> {
    let mut state = 0x2545_f491_4f6c_dd1du64;
    let img = image::RgbImage::from_fn(1200, 1200, |_, _| {
        state ^= state << 13;
        state ^= state >> 7;
        state ^= state << 17;
        image::Rgb([state as u8, (state >> 8) as u8, (state >> 16) as u8])
    });
    let mut png = Vec::new();
    DynamicImage::ImageRgb8(img)
        .write_to(&mut std::io::Cursor::new(&mut png), image::ImageFormat::Png)
        .unwrap();
    png
}

/// Events until the connection is dropped or 20 s after `stopped`: how long after it the first
/// frame was reported lost (timed out) and the silence dropped the connection.
async fn loss_and_drop_after(
    events: &mut tre::client::Events,
    stopped: Instant,
) -> (Option<Duration>, Option<Duration>) {
    let (mut first_lost, mut disconnected) = (None, None);
    while disconnected.is_none() && stopped.elapsed() < Duration::from_secs(20) {
        let wait = Duration::from_secs(20).saturating_sub(stopped.elapsed());
        match tokio::time::timeout(wait, events.recv()).await {
            Ok(Some(Event::Lost { reason, .. })) if first_lost.is_none() => {
                assert_eq!(reason, LostReason::TimedOut);
                first_lost = Some(stopped.elapsed());
            }
            Ok(Some(Event::Disconnected { reason })) => {
                assert!(reason.to_string().contains("nothing heard"), "{reason}");
                disconnected = Some(stopped.elapsed());
            }
            Ok(Some(_)) => {}
            Ok(None) | Err(_) => break,
        }
    }
    (first_lost, disconnected)
}

/// A server that stops mid-stream (SIGSTOP: hung, with its socket open) once froze the client:
/// once the frames filled the connection, the write in progress blocked the whole session, so
/// no frame was reported lost, the silence check never ran and the client never reconnected,
/// for as long as the server stayed stopped. Now frames time out on time, the silence drops the
/// connection, and the session carries on once the server answers again.
#[test]
fn a_hung_server_is_reported_on_time_and_the_session_recovers() {
    let (_serial, _dir, mut server) = serve(&[]);
    server.wait_ready();
    let noise = noise_png();
    let signal = |sig: &str| {
        let pid = server.child.id().to_string();
        assert!(Command::new("kill")
            .args([sig, &pid])
            .status()
            .unwrap()
            .success());
    };
    rt().block_on(async {
        let mut cfg = session_config(server.addr);
        cfg.rate = Rate::Fixed(10.0);
        cfg.frame_timeout = Duration::from_secs(1);
        cfg.silence_timeout = Duration::from_secs(4);
        cfg.connect_timeout = Duration::from_secs(1);
        cfg.reconnect.initial = Duration::from_millis(100);
        cfg.reconnect.max = Duration::from_millis(500);
        let (mut sender, mut events) = Session::connect(cfg).await.unwrap().split();
        signal("-STOP");
        let stopped = Instant::now();
        let frames = tokio::spawn(async move {
            // Until the session ends (the test drops the events): the send may block, paced.
            while sender.send(Frame::rgb(noise.clone())).await.is_ok() {}
        });
        let (first_lost, disconnected) = loss_and_drop_after(&mut events, stopped).await;
        signal("-CONT");
        let first_lost = first_lost.expect("no frame reported lost while the server was stopped");
        assert!(
            first_lost < Duration::from_secs(5),
            "the first loss came {first_lost:?} after the stop"
        );
        let disconnected = disconnected.expect("the silence never dropped the connection");
        assert!(
            disconnected < Duration::from_secs(12),
            "dropped {disconnected:?} after the stop"
        );
        // The server answers again: the session reconnects and frames come back.
        let mut recovered = false;
        while let Ok(Some(event)) =
            tokio::time::timeout(Duration::from_secs(60), events.recv()).await
        {
            if matches!(event, Event::Result(_)) {
                recovered = true;
                break;
            }
        }
        assert!(recovered, "no result after the server came back");
        drop(events);
        frames.abort();
    });
    server.kill();
}

/// A server at its `--max-connections` limit: `tre client` says why it cannot connect (the
/// server's own `overloaded` message, where it once said only "not ready yet (HTTP 503)"), and
/// connects as soon as the place is free. It once kept its readiness check's connection open
/// for the whole session, which on such a server held the place its own stream needed until
/// the server closed the idle connection (`--request-timeout-ms`, 60 s here).
#[test]
fn a_server_at_its_connection_limit_is_named_and_the_client_connects_once_a_place_frees() {
    crate::common::skip_unless_shared!("data/real-rgbd");
    use std::io::Read;
    let more = ["--max-connections", "1", "--request-timeout-ms", "60000"];
    let (_serial, dir, server) = serve(&more);
    make_frames(&dir.path().join("frames"));
    server.wait_ready();
    // A kept-alive connection, seen served, holds the only place for 3 s.
    let holder = served_connection(server.addr);
    let release = crate::common::spawn_named("release-holder", move || {
        std::thread::sleep(Duration::from_secs(3));
        drop(holder);
    });
    let out = dir.path().join("out");
    let start = Instant::now();
    let mut child = two_frame_client(server.addr, &dir.path().join("frames"), &out);
    let mut stderr = child.stderr.take().unwrap();
    let reader = crate::common::spawn_named("client-stderr", move || {
        let mut text = String::new();
        let _ = stderr.read_to_string(&mut text);
        text
    });
    let status = loop {
        if let Some(status) = child.try_wait().unwrap() {
            break status;
        }
        if start.elapsed() > Duration::from_secs(30) {
            let _ = child.kill();
            let _ = child.wait();
            panic!(
                "no results 30 s on (the place was freed at 3 s): {}",
                reader.join().unwrap()
            );
        }
        std::thread::sleep(Duration::from_millis(100));
    };
    release.join().unwrap();
    let log = reader.join().unwrap();
    assert!(status.success(), "{log}");
    assert!(
        log.contains("overloaded") && log.contains("--max-connections"),
        "the reason is not named: {log}"
    );
    let csv = std::fs::read_to_string(out.join("frames.csv")).unwrap();
    assert_eq!(
        csv.lines().filter(|l| l.ends_with(",ok")).count(),
        2,
        "{csv}"
    );
}

/// A kept-alive connection to `addr` that has been served (`GET /healthz` answered 200).
fn served_connection(addr: SocketAddr) -> std::net::TcpStream {
    use std::io::{Read, Write};
    loop {
        let mut tcp = std::net::TcpStream::connect(addr).unwrap();
        tcp.write_all(b"GET /healthz HTTP/1.1\r\nHost: x\r\n\r\n")
            .unwrap();
        let mut buf = [0u8; 512];
        let n = tcp.read(&mut buf).unwrap();
        if buf[..n].starts_with(b"HTTP/1.1 200") {
            break tcp;
        }
        std::thread::sleep(Duration::from_millis(50));
    }
}

/// `tre client` sending two of the frames in `frames` to `addr`'s stream, reconnecting every
/// 0.2–1 s, writing into `out`; its stderr piped.
fn two_frame_client(addr: SocketAddr, frames: &Path, out: &Path) -> Child {
    Command::new(env!("CARGO_BIN_EXE_tre"))
        .args(["client", "--server", &format!("ws://{addr}/v1/stream")])
        .arg("--frames")
        .arg(frames)
        .args(["--as-fast-as-results", "--mode", "rgb", "--normals", "ls"])
        .args(["--limit", "2", "--reconnect-initial-ms", "200"])
        .args(["--reconnect-max-ms", "1000", "--out"])
        .arg(out)
        .stderr(Stdio::piped())
        .stdout(Stdio::null())
        .spawn()
        .unwrap()
}
