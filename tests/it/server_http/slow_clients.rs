//! Slow, stalled and vanishing clients: oversize bodies sent whole, stalled and trickling
//! uploads, the minimum body rate, clients that stop reading, header deadlines and idle
//! connections.

use super::*;

#[test]
fn a_client_that_sends_a_whole_oversize_body_first_still_reads_the_413() {
    crate::common::skip_unless_shared!("data/real-rgbd");
    // Like Python's http.client: write the whole request, then read the answer. 30 MB against
    // an 8 MB limit is more than loopback's socket buffers hold, so the server must read the
    // rest of the body rather than close on it.
    let server = Server::start(&["--workers", "1", "--max-body-bytes", "8000000"]);
    let body = vec![0u8; 30_000_000];
    let mut s = TcpStream::connect(server.addr).unwrap();
    s.set_read_timeout(Some(std::time::Duration::from_secs(60)))
        .unwrap();
    let head = format!(
        "POST /v1/roughness HTTP/1.1\r\nHost: x\r\nContent-Type: image/png\r\nContent-Length: {}\r\nConnection: close\r\n\r\n",
        body.len()
    );
    s.write_all(head.as_bytes()).unwrap();
    s.write_all(&body)
        .expect("the server stopped reading before the body ended");
    let mut answer = String::new();
    std::io::Read::read_to_string(&mut s, &mut answer).unwrap();
    assert!(answer.starts_with("HTTP/1.1 413"), "{answer}");
    assert!(answer.contains("\"too_large\""), "{answer}");
    rt().block_on(still_serves(&server));
}

/// A client that sends its headers and a few bytes of body, then nothing, holds none of the
/// `--max-concurrent` places (the only one here): other clients are served meanwhile, and it
/// hears 408 `request_timeout` at `--body-timeout-ms`.
#[test]
fn a_client_that_stalls_mid_upload_holds_no_place_and_hears_408() {
    crate::common::skip_unless_shared!("data/real-rgbd");
    use std::io::Read;
    let server = Server::start(&[
        "--workers",
        "1",
        "--max-concurrent",
        "1",
        "--body-timeout-ms",
        "1500",
    ]);
    let frame = std::fs::read(real("slambook2_ch7/1.png")).unwrap();
    let mut stalled = TcpStream::connect(server.addr).unwrap();
    let head = "POST /v1/roughness HTTP/1.1\r\nHost: x\r\nContent-Type: image/png\r\nContent-Length: 100000\r\n\r\n";
    stalled.write_all(head.as_bytes()).unwrap();
    stalled.write_all(&frame[..4]).unwrap();
    rt().block_on(still_serves(&server));
    stalled
        .set_read_timeout(Some(std::time::Duration::from_secs(30)))
        .unwrap();
    let mut answer = Vec::new();
    let _ = stalled.read_to_end(&mut answer);
    let answer = String::from_utf8_lossy(&answer);
    assert!(answer.starts_with("HTTP/1.1 408"), "{answer}");
    assert!(
        answer.contains("\"request_timeout\"") && answer.contains("--body-timeout-ms"),
        "{answer}"
    );
    rt().block_on(still_serves(&server));
}

/// Eighty connections sending a body at one byte a second (the defaults: 64 places) do not
/// stop another client's frame: it is answered 200 while they trickle, and the trickling
/// uploads end with 408 (at the end of the first `--min-body-rate` window, 5 s).
#[test]
fn eighty_trickling_uploads_do_not_starve_a_ready_request() {
    crate::common::skip_unless_shared!("data/real-rgbd");
    let server = Server::start(&["--workers", "1", "--body-timeout-ms", "6000"]);
    let head = "POST /v1/roughness HTTP/1.1\r\nHost: x\r\nContent-Type: image/png\r\nContent-Length: 100000\r\n\r\n";
    let mut trickles: Vec<TcpStream> = (0..80)
        .map(|_| {
            let mut t = TcpStream::connect(server.addr).unwrap();
            t.write_all(head.as_bytes()).unwrap();
            t
        })
        .collect();
    let stop = std::sync::Arc::new(std::sync::atomic::AtomicBool::new(false));
    let feeder = {
        let mut writers: Vec<TcpStream> = trickles.iter().map(|t| t.try_clone().unwrap()).collect();
        let stop = stop.clone();
        crate::common::spawn_named("trickle-feeder", move || {
            while !stop.load(std::sync::atomic::Ordering::Relaxed) {
                for w in &mut writers {
                    let _ = w.write_all(b"x");
                }
                std::thread::sleep(std::time::Duration::from_secs(1));
            }
        })
    };
    std::thread::sleep(std::time::Duration::from_secs(1));
    let started = std::time::Instant::now();
    rt().block_on(still_serves(&server));
    // Generous: the frame itself takes well under a second; the trickle lasts 6 s.
    assert!(
        started.elapsed() < std::time::Duration::from_secs(5),
        "a ready frame waited {:?} behind trickling uploads",
        started.elapsed()
    );
    let mut first = trickles.remove(0);
    first
        .set_read_timeout(Some(std::time::Duration::from_secs(30)))
        .unwrap();
    let mut answer = [0u8; 12];
    std::io::Read::read_exact(&mut first, &mut answer).unwrap();
    assert_eq!(
        &answer,
        b"HTTP/1.1 408",
        "{}",
        String::from_utf8_lossy(&answer)
    );
    stop.store(true, std::sync::atomic::Ordering::Relaxed);
    feeder.join().unwrap();
}

/// An RGB PNG of `w`×`h` that does not compress (a deterministic noise), about 3 B per pixel.
fn noise_png(w: u32, h: u32) -> Vec<u8> {
    let mut state = 0x2545_f491_u32;
    let img = image::RgbImage::from_fn(w, h, |_, _| {
        state ^= state << 13;
        state ^= state >> 17;
        state ^= state << 5;
        let [a, b, c, _] = state.to_le_bytes();
        image::Rgb([a, b, c])
    });
    let mut out = Vec::new();
    image::DynamicImage::ImageRgb8(img)
        .write_to(&mut std::io::Cursor::new(&mut out), image::ImageFormat::Png)
        .unwrap();
    out
}

/// Sends `body` as a PNG upload at `chunk` bytes every `every` and returns the answer, read as
/// it comes (the server may answer and close before the body is all sent).
fn paced_upload(server: &Server, body: &[u8], chunk: usize, every: std::time::Duration) -> String {
    use std::io::Read;
    let mut tcp = TcpStream::connect(server.addr).unwrap();
    let mut reader = tcp.try_clone().unwrap();
    let reading = crate::common::spawn_named("answer-reader", move || {
        let mut answer = Vec::new();
        let _ = reader.read_to_end(&mut answer);
        String::from_utf8_lossy(&answer).into_owned()
    });
    let head = format!(
        "POST /v1/roughness?mode=rgb&normals=ls HTTP/1.1\r\nHost: x\r\nContent-Type: image/png\r\nContent-Length: {}\r\nConnection: close\r\n\r\n",
        body.len()
    );
    tcp.write_all(head.as_bytes()).unwrap();
    for piece in body.chunks(chunk) {
        if reading.is_finished() || tcp.write_all(piece).is_err() {
            break;
        }
        std::thread::sleep(every);
    }
    reading.join().unwrap()
}

/// `--min-body-rate` (1 KiB/s by default, over 5 s windows): an upload at about 100 B/s hears
/// 408 naming the option after one window, long before `--body-timeout-ms` (60 s here); one at
/// about 2.5 KiB/s, slow but above the rate, lasting beyond a window, is answered 200.
#[test]
fn a_body_below_the_minimum_rate_hears_408_and_one_above_it_is_served() {
    let server = Server::start(&["--workers", "1", "--body-timeout-ms", "60000"]);
    let frame = noise_png(96, 64);
    assert!(frame.len() > 15_000, "{} bytes", frame.len());
    let started = std::time::Instant::now();
    let (slow, steady) = std::thread::scope(|s| {
        let slow =
            s.spawn(|| paced_upload(&server, &frame, 20, std::time::Duration::from_millis(200)));
        let steady =
            s.spawn(|| paced_upload(&server, &frame, 500, std::time::Duration::from_millis(200)));
        (slow.join().unwrap(), steady.join().unwrap())
    });
    assert!(slow.starts_with("HTTP/1.1 408"), "{slow}");
    assert!(
        slow.contains("\"request_timeout\"") && slow.contains("--min-body-rate"),
        "{slow}"
    );
    assert!(steady.starts_with("HTTP/1.1 200"), "{steady}");
    assert!(
        started.elapsed() < std::time::Duration::from_secs(30),
        "took {:?}",
        started.elapsed()
    );
}

/// Posts `frame` for `query` over a socket with a receive buffer of `recv_buffer` bytes (so that
/// a large answer fills the connection) and returns the socket without reading.
async fn post_unread(
    server: &Server,
    query: &str,
    frame: &[u8],
    recv_buffer: u32,
) -> tokio::net::TcpStream {
    use tokio::io::AsyncWriteExt;
    let socket = tokio::net::TcpSocket::new_v4().unwrap();
    socket.set_recv_buffer_size(recv_buffer).unwrap();
    let mut tcp = socket.connect(server.addr).await.unwrap();
    let head = format!(
        "POST /v1/roughness?{query} HTTP/1.1\r\nHost: x\r\nContent-Type: image/png\r\nContent-Length: {}\r\n\r\n",
        frame.len()
    );
    tcp.write_all(head.as_bytes()).await.unwrap();
    tcp.write_all(frame).await.unwrap();
    tcp
}

/// Reads an HTTP answer from `tcp`, `chunk` bytes at a time with `pause` before each read,
/// until its body is complete or the connection ends: (answer bytes, whether complete).
async fn read_answer(
    tcp: &mut tokio::net::TcpStream,
    chunk: usize,
    pause: std::time::Duration,
) -> (Vec<u8>, bool) {
    use tokio::io::AsyncReadExt;
    let mut answer = Vec::new();
    let mut buf = vec![0u8; chunk];
    loop {
        tokio::time::sleep(pause).await;
        let read = tokio::time::timeout(std::time::Duration::from_secs(30), tcp.read(&mut buf));
        match read.await.expect("no byte and no end within 30 s") {
            Ok(0) | Err(_) => return (answer, false),
            Ok(n) => answer.extend_from_slice(&buf[..n]),
        }
        let text = String::from_utf8_lossy(&answer);
        if let Some(end) = text.find("\r\n\r\n") {
            let length: usize = text[..end]
                .lines()
                .find_map(|l| l.strip_prefix("content-length: "))
                .expect("a content-length")
                .parse()
                .unwrap();
            if answer.len() >= end + 4 + length {
                return (answer, true);
            }
        }
    }
}

/// A client that stops reading its answer, such as a hung process with its socket open, once
/// kept its connection and the answer in it (here 640×480 float maps, about 7 MB, more than the
/// system's socket buffers hold) until the server stopped, and held up its shutdown for the
/// whole grace time. Now the connection ends once the client has taken nothing for
/// `--stall-timeout-ms`, so the answer it reads later is cut short; a client that reads slowly
/// but steadily still gets all of it.
#[test]
fn a_client_that_stops_reading_its_answer_loses_the_connection_and_a_slow_one_does_not() {
    crate::common::skip_unless_shared!("data/real-rgbd");
    let server = Server::start(&["--workers", "1", "--stall-timeout-ms", "1500"]);
    let frame = std::fs::read(real("slambook2_ch7/1.png")).unwrap();
    rt().block_on(async {
        let big = "mode=rgb&normals=ls&format=npy&outputs=depth,normals,slope";
        let mut stuck = post_unread(&server, big, &frame, 4096).await;
        tokio::time::sleep(std::time::Duration::from_secs(5)).await;
        let (answer, complete) = read_answer(&mut stuck, 1 << 20, Default::default()).await;
        assert!(answer.starts_with(b"HTTP/1.1 200"));
        assert!(
            !complete,
            "all {} bytes arrived after a 5 s stall",
            answer.len()
        );
        // Slow but steady (at most 256 KiB every 0.2 s, about 6 s for the same answer): the
        // server waits on it throughout, never 1.5 s without progress.
        let mut slow = post_unread(&server, big, &frame, 256 << 10).await;
        let pause = std::time::Duration::from_millis(200);
        let (answer, complete) = read_answer(&mut slow, 256 << 10, pause).await;
        assert!(
            complete,
            "a slow reader was cut off after {} bytes",
            answer.len()
        );
        still_serves(&server).await;
    });
}

/// Whether the server closes `tcp` within `within` while it is sent one byte of `bytes` every
/// 0.2 s (nothing once they run out). A server that answers instead is a failure.
fn closed_within(mut tcp: TcpStream, bytes: &[u8], within: std::time::Duration) -> bool {
    use std::io::Read;
    let start = std::time::Instant::now();
    tcp.set_read_timeout(Some(std::time::Duration::from_millis(200)))
        .unwrap();
    let mut sent = 0;
    while start.elapsed() < within {
        if sent < bytes.len() && tcp.write_all(&bytes[sent..=sent]).is_ok() {
            sent += 1;
        }
        let mut buf = [0u8; 256];
        match tcp.read(&mut buf) {
            Ok(0) => return true,
            Ok(n) => panic!("an answer: {}", String::from_utf8_lossy(&buf[..n])),
            Err(e) if e.kind() == std::io::ErrorKind::WouldBlock => {}
            Err(e) if e.kind() == std::io::ErrorKind::TimedOut => {}
            Err(_) => return true,
        }
    }
    false
}

/// Request headers sent a byte at a time (slowloris), and a connection opened and left idle,
/// were once kept until the server stopped: a task and a file descriptor each, so enough of
/// them exhaust the process's descriptors. Now the headers must arrive within
/// `--header-timeout-ms`: a client that sent part of them hears 408, an idle kept-alive
/// connection is closed without a word; requests that arrive in time are served, on new and
/// kept-alive connections alike.
#[test]
fn request_headers_have_a_deadline_and_idle_connections_are_closed() {
    crate::common::skip_unless_shared!("data/real-rgbd");
    use std::io::Read;
    let server = Server::start(&["--workers", "1", "--header-timeout-ms", "1500"]);
    let within = std::time::Duration::from_secs(8);
    let head = b"POST /v1/roughness HTTP/1.1\r\nHost: x\r\nContent-Type: image/png\r\nX-Pad: aaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaa";
    let mut trickling = TcpStream::connect(server.addr).unwrap();
    let start = std::time::Instant::now();
    trickling
        .set_read_timeout(Some(std::time::Duration::from_millis(200)))
        .unwrap();
    let mut answer = Vec::new();
    for b in head.iter().cycle() {
        assert!(
            start.elapsed() < within,
            "headers sent a byte every 0.2 s still held the connection 8 s on"
        );
        let _ = trickling.write_all(&[*b]);
        let mut buf = [0u8; 512];
        match trickling.read(&mut buf) {
            Ok(0) => break,
            Ok(n) => answer.extend_from_slice(&buf[..n]),
            Err(e)
                if matches!(
                    e.kind(),
                    std::io::ErrorKind::WouldBlock | std::io::ErrorKind::TimedOut
                ) => {}
            Err(_) => break,
        }
    }
    let answer = String::from_utf8_lossy(&answer);
    assert!(answer.starts_with("HTTP/1.1 408"), "{answer}");
    assert!(answer.contains("--header-timeout-ms"), "{answer}");
    let idle = TcpStream::connect(server.addr).unwrap();
    assert!(
        closed_within(idle, b"", within),
        "an idle connection was still open 8 s on"
    );
    // Two requests 1 s apart on one kept-alive connection are both served.
    rt().block_on(async {
        let client = reqwest::Client::new();
        for _ in 0..2 {
            let resp = client.get(format!("{}/healthz", server.url())).send().await;
            assert_eq!(resp.unwrap().status().as_u16(), 200);
            tokio::time::sleep(std::time::Duration::from_secs(1)).await;
        }
        still_serves(&server).await;
    });
}
