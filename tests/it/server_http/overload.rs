//! Overload is refused at once while accepted work finishes; SIGTERM drains; clients that left
//! give back their queue slots; connections over the limit are answered 503.

use super::*;

#[test]
fn overload_is_refused_at_once_and_accepted_work_finishes() {
    crate::common::skip_unless_shared!("data/real-rgbd");
    let server = Server::start(&["--workers", "1", "--queue", "1"]);
    let url = format!("{}/v1/roughness", server.url());
    let frame = std::fs::read(real("slambook2_ch7/1.png")).unwrap();
    let outcomes = rt().block_on(async {
        let client = reqwest::Client::new();
        let order = std::sync::Arc::new(std::sync::atomic::AtomicUsize::new(0));
        // The first request alone, until the worker has started it (its batch is counted):
        // on a busy machine the burst could otherwise come before the worker takes it from
        // the queue, and find both taken.
        let tasks: Vec<_> = (0..12)
            .map(|i| {
                let (client, url, frame, order) =
                    (client.clone(), url.clone(), frame.clone(), order.clone());
                let task = tokio::spawn(async move {
                    let resp = client
                        .post(&url)
                        .header("content-type", "image/png")
                        .body(frame)
                        .send()
                        .await
                        .unwrap();
                    let status = resp.status().as_u16();
                    let retry = resp
                        .headers()
                        .get("retry-after")
                        .map(|v| v.to_str().unwrap().to_owned());
                    let body = resp.bytes().await.unwrap();
                    let finished = order.fetch_add(1, std::sync::atomic::Ordering::SeqCst);
                    (status, retry, body, finished)
                });
                if i == 0 {
                    let started = std::time::Instant::now();
                    while !String::from_utf8_lossy(&get(server.addr, "/metrics").1)
                        .contains("tre_batch_size_count 1")
                    {
                        assert!(
                            started.elapsed().as_secs() < 30,
                            "the first frame never started"
                        );
                        std::thread::sleep(std::time::Duration::from_millis(5));
                    }
                }
                task
            })
            .collect();
        let mut out = Vec::new();
        for t in tasks {
            out.push(t.await.unwrap());
        }
        out
    });
    assert_refused_at_once(&server, &outcomes);
}

/// A request's status, `Retry-After`, body, and its place in the order the answers came.
type Outcome = (u16, Option<String>, axum::body::Bytes, usize);

/// Only 200 and 503 `overloaded` with `Retry-After`; the maps are maps; every refusal came back
/// before the last accepted frame; the metrics count the refusals.
fn assert_refused_at_once(server: &Server, outcomes: &[Outcome]) {
    let ok: Vec<_> = outcomes.iter().filter(|o| o.0 == 200).collect();
    let refused: Vec<_> = outcomes.iter().filter(|o| o.0 == 503).collect();
    assert_eq!(
        ok.len() + refused.len(),
        outcomes.len(),
        "only 200 and 503 expected"
    );
    assert!(
        ok.len() >= 2 && !refused.is_empty(),
        "{} ok, {} refused",
        ok.len(),
        refused.len()
    );
    for r in &refused {
        assert_eq!(r.1.as_deref(), Some("1"), "503 without Retry-After");
        let v: serde_json::Value = serde_json::from_slice(&r.2).unwrap();
        assert_eq!(v["error"]["code"], "overloaded");
    }
    for o in &ok {
        png16_values(&o.2);
    }
    // Refusals come back while accepted frames are still running: every refusal finished
    // before the last accepted frame did.
    let last_ok = ok.iter().map(|o| o.3).max().unwrap();
    assert!(refused.iter().all(|r| r.3 < last_ok));
    let metrics = String::from_utf8(get(server.addr, "/metrics").1).unwrap();
    assert!(metrics.contains(&format!(
        "tre_requests_total{{endpoint=\"roughness\",outcome=\"overloaded\"}} {}",
        refused.len()
    )));
    assert!(metrics.contains("tre_queue_capacity 1"));
}

#[test]
fn sigterm_finishes_in_flight_work_then_exits() {
    crate::common::skip_unless_shared!("data/real-rgbd");
    let server = Server::start(&["--workers", "1"]);
    let url = format!("{}/v1/roughness", server.url());
    let frame = std::fs::read(real("slambook2_ch7/1.png")).unwrap();
    let rt = rt();
    let pending = rt.spawn(async move { post(&url, "image/png", frame).await.status().as_u16() });
    // Wait until the frame is running (the queue has taken it), then ask the server to stop.
    let start = std::time::Instant::now();
    loop {
        let text = String::from_utf8(get(server.addr, "/metrics").1).unwrap_or_default();
        if text.contains("tre_batch_size_count 1")
            || start.elapsed() > std::time::Duration::from_secs(20)
        {
            break;
        }
        std::thread::sleep(std::time::Duration::from_millis(5));
    }
    let status = server.terminate();
    assert!(status.success(), "exit status {status}");
    assert_eq!(
        rt.block_on(pending).unwrap(),
        200,
        "the in-flight request was not finished"
    );
}

#[test]
fn clients_that_left_give_their_queue_slots_to_new_frames() {
    crate::common::skip_unless_shared!("data/real-rgbd");
    // One worker, a queue of one, and a short timeout: a frame that outlives its client's
    // timeout must not keep the only slot from the next client while the worker is busy.
    let server = Server::start(&[
        "--workers",
        "1",
        "--queue",
        "1",
        "--request-timeout-ms",
        "300",
        // The slow frame is 12 Mpx, over the 4 Mi default.
        "--max-pixels",
        "12000000",
    ]);
    let url = format!("{}/v1/roughness", server.url());
    let small = std::fs::read(real("slambook2_ch7/1.png")).unwrap();
    // A slow frame: 4000×3000, every output map brought back to that size.
    let big = {
        let rgb = image::open(real("slambook2_ch7/1.png")).unwrap().to_rgb8();
        let up = image::imageops::resize(&rgb, 4000, 3000, image::imageops::FilterType::Nearest);
        let mut out = std::io::Cursor::new(Vec::new());
        up.write_to(&mut out, image::ImageFormat::Jpeg).unwrap();
        out.into_inner()
    };
    let rt = rt();
    let slow_url = format!("{url}?outputs=depth,normals,slope,traversable,boundary");
    let mut slow = rt.spawn(async move {
        let resp = post(&slow_url, "image/jpeg", big).await;
        (resp.status(), resp.text().await.unwrap())
    });
    let start = std::time::Instant::now();
    while !String::from_utf8(get(server.addr, "/metrics").1)
        .unwrap_or_default()
        .contains("tre_batch_size_count 1")
    {
        assert!(
            !slow.is_finished() && start.elapsed() < std::time::Duration::from_secs(20),
            "the slow frame never started: {:?}",
            slow.is_finished().then(|| rt.block_on(&mut slow))
        );
        std::thread::sleep(std::time::Duration::from_millis(5));
    }
    rt.block_on(async {
        // Queued behind the slow frame; its client's timeout ends before the worker is free.
        let (s, code, message) = error_of(post(&url, "image/png", small.clone()).await).await;
        assert_eq!((s, code.as_str()), (503, "timeout"), "{message}");
        // Its job is still queued, but its client is gone: the next frame takes the slot.
        let resp = post(&url, "image/png", small).await;
        if resp.status().as_u16() != 200 {
            let (s, code, message) = error_of(resp).await;
            assert_eq!((s, code.as_str()), (503, "timeout"), "{message}");
        }
    });
    rt.block_on(slow).unwrap();
}

/// Connections were once unlimited in number: each held a task and a file descriptor until its
/// deadlines ran out, so enough of them, idle, exhausted the process's descriptors and left
/// the server unable to take any. Over `--max-connections` a request is now answered 503
/// `overloaded` with `Retry-After` at once, past twice the limit a connection is closed
/// unanswered, and once the holders leave the server takes connections again.
#[test]
fn connections_over_the_limit_are_answered_503_at_once() {
    crate::common::skip_unless_shared!("data/real-rgbd");
    let server = Server::start(&["--workers", "1", "--max-connections", "2"]);
    // Two kept-alive connections that have been served hold both places. (A connection the
    // server is still closing, such as the start-up probe's, may hold one for a moment: a
    // holder refused then is opened again.)
    let mut early = 0;
    let holders = served_holders(server.addr, &mut early);
    let refused = |tcp: &mut TcpStream| -> Option<Vec<u8>> {
        let req = b"GET /healthz HTTP/1.1\r\nHost: x\r\n\r\n";
        tcp.write_all(req).ok()?;
        Some(refused_reply(tcp))
    };
    // Two more get the answer (and keep the refusals' places while they are open); a fifth
    // finds both kinds of place taken and is closed unanswered.
    let mut waiting: Vec<TcpStream> = (0..3)
        .map(|_| TcpStream::connect(server.addr).unwrap())
        .collect();
    std::thread::sleep(std::time::Duration::from_millis(300));
    let answers: Vec<String> = waiting
        .iter_mut()
        .map(|t| String::from_utf8_lossy(&refused(t).unwrap_or_default()).into_owned())
        .collect();
    for answer in &answers[..2] {
        assert!(answer.starts_with("HTTP/1.1 503"), "{answer}");
        assert!(answer.contains("retry-after: 1"), "{answer}");
        assert!(answer.contains("\"code\":\"overloaded\""), "{answer}");
        assert!(answer.contains("--max-connections"), "{answer}");
    }
    assert_eq!(answers[2], "", "past twice the limit: closed unanswered");
    drop(waiting);
    // A client that sends its whole 3 MB request before reading (as Python's http.client does)
    // gets the answer too, not a broken pipe: the body is read and dropped first.
    std::thread::sleep(std::time::Duration::from_millis(300));
    let mut eager = TcpStream::connect(server.addr).unwrap();
    let body = vec![7u8; 3 << 20];
    let head = format!(
        "POST /v1/roughness HTTP/1.1\r\nHost: x\r\nContent-Type: image/png\r\nContent-Length: {}\r\n\r\n",
        body.len()
    );
    eager.write_all(head.as_bytes()).unwrap();
    eager
        .write_all(&body)
        .expect("the refused request's body was not read");
    let answer = String::from_utf8_lossy(&refused_reply(&mut eager)).into_owned();
    assert!(answer.starts_with("HTTP/1.1 503"), "{answer}");
    assert!(answer.contains("\"code\":\"overloaded\""), "{answer}");
    drop(holders);
    // The places are free again: the server serves.
    let start = std::time::Instant::now();
    while get(server.addr, "/healthz").0 != 200 {
        early += 1;
        assert!(
            start.elapsed() < std::time::Duration::from_secs(5),
            "the places were not freed"
        );
        std::thread::sleep(std::time::Duration::from_millis(50));
    }
    let metrics = settled_metrics(server.addr, &mut early);
    let refused_total = format!("tre_connections_refused_total {}\n", 4 + early);
    assert!(metrics.contains(&refused_total), "{metrics}");
    assert!(metrics.contains("tre_connections_open 1\n"), "{metrics}");
    rt().block_on(still_serves(&server));
}

/// The metrics once the connection of a poll before them has left: it may still be closing on
/// the server's side when they are read, so they are read again until only the metrics
/// request's own connection is open (5 s at most); each refused read adds one to `early`.
fn settled_metrics(addr: std::net::SocketAddr, early: &mut usize) -> String {
    let start = std::time::Instant::now();
    loop {
        let (status, body) = get(addr, "/metrics");
        let metrics = String::from_utf8(body).unwrap();
        if status != 200 {
            *early += 1;
        } else if metrics.contains("tre_connections_open 1\n")
            || start.elapsed() > std::time::Duration::from_secs(5)
        {
            return metrics;
        }
        std::thread::sleep(std::time::Duration::from_millis(50));
    }
}

/// Two kept-alive connections to `addr` that have been served; each refused first (a place
/// still held by a connection the server is closing) adds one to `early`.
fn served_holders(addr: std::net::SocketAddr, early: &mut usize) -> Vec<TcpStream> {
    (0..2)
        .map(|_| loop {
            use std::io::Read;
            let mut tcp = TcpStream::connect(addr).unwrap();
            tcp.set_read_timeout(Some(std::time::Duration::from_secs(5)))
                .unwrap();
            tcp.write_all(b"GET /healthz HTTP/1.1\r\nHost: x\r\n\r\n")
                .unwrap();
            let mut raw = Vec::new();
            let mut buf = [0u8; 512];
            while !raw.ends_with(b"}") {
                let n = tcp.read(&mut buf).unwrap();
                assert!(n > 0, "closed: {}", String::from_utf8_lossy(&raw));
                raw.extend_from_slice(&buf[..n]);
            }
            if raw.starts_with(b"HTTP/1.1 200") {
                break tcp;
            }
            *early += 1;
            std::thread::sleep(std::time::Duration::from_millis(50));
        })
        .collect()
}

/// What a refused connection is told before it is closed (5 s at most).
fn refused_reply(tcp: &mut TcpStream) -> Vec<u8> {
    use std::io::Read;
    tcp.set_read_timeout(Some(std::time::Duration::from_secs(5)))
        .unwrap();
    let mut raw = Vec::new();
    let _ = tcp.read_to_end(&mut raw);
    raw
}
