//! A fake one-at-a-time HTTP service for the load tester, and the loads run against it and
//! against the real service, shared by the load-test tests (`tests/it/loadtest/`) and the
//! load-test bench (`benches/loadtest.rs`).
#![allow(dead_code)] // Not every user uses every helper.

use std::io::{BufRead, BufReader, Read, Write};
use std::net::{SocketAddr, TcpListener, TcpStream};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use tre::loadtest::{run_on, Frames, Load, LoadConfig, LoadSource, Report, Target};

/// Runs `f` on a two-thread runtime.
pub(crate) fn block_on<F: std::future::Future>(f: F) -> F::Output {
    tokio::runtime::Builder::new_multi_thread()
        .worker_threads(2)
        .enable_all()
        .build()
        .expect("runtime")
        .block_on(f)
}

/// A tiny one-at-a-time HTTP service: each request holds the service for `service`, except the
/// first one handled `stall_after` after the first request, which holds it for `stall`.
/// `answer(n)` gives the status and body of request `n`.
pub(crate) struct Fake {
    /// How long each request holds the service.
    pub service: Duration,
    /// `(stall_after, stall)`: one request held longer, or none.
    pub stall: Option<(Duration, Duration)>,
    /// The status and body of request `n`.
    pub answer: fn(u64) -> (u16, &'static str),
}

struct FakeState {
    first: Option<Instant>,
    stalled: bool,
    n: u64,
}

impl Fake {
    /// A service that answers `answer(n)` to request `n` after `ms` milliseconds, never stalling.
    pub(crate) fn steady(ms: u64, answer: fn(u64) -> (u16, &'static str)) -> SocketAddr {
        Fake {
            service: Duration::from_millis(ms),
            stall: None,
            answer,
        }
        .start()
    }

    /// Listens on a loopback port, serving each connection on a thread of its own.
    pub(crate) fn start(self) -> SocketAddr {
        let listener = TcpListener::bind("127.0.0.1:0").expect("bind");
        let addr = listener.local_addr().expect("addr");
        let fake = Arc::new(self);
        let state = Arc::new(Mutex::new(FakeState {
            first: None,
            stalled: false,
            n: 0,
        }));
        std::thread::Builder::new()
            .name("fake-accept".into())
            .spawn(move || {
                for conn in listener.incoming().flatten() {
                    let (fake, state) = (fake.clone(), state.clone());
                    let _ = std::thread::Builder::new()
                        .name("fake-conn".into())
                        .spawn(move || fake.serve(conn, &state));
                }
            })
            .expect("thread");
        addr
    }

    /// Serves the keep-alive requests of one connection.
    fn serve(&self, conn: TcpStream, state: &Mutex<FakeState>) {
        let mut reader = BufReader::new(conn.try_clone().expect("clone"));
        let mut conn = conn;
        loop {
            let mut length = 0usize;
            let mut line = String::new();
            let mut first_line = true;
            loop {
                line.clear();
                match reader.read_line(&mut line) {
                    Ok(0) | Err(_) => return,
                    Ok(_) => {}
                }
                if line == "\r\n" && !first_line {
                    break;
                }
                first_line = false;
                let lower = line.to_ascii_lowercase();
                if let Some(v) = lower.strip_prefix("content-length:") {
                    length = v.trim().parse().expect("length");
                }
            }
            let mut body = vec![0; length];
            if reader.read_exact(&mut body).is_err() {
                return;
            }
            let n = {
                let mut s = state.lock().expect("state");
                let first = *s.first.get_or_insert_with(Instant::now);
                let hold = match self.stall {
                    Some((after, stall)) if !s.stalled && first.elapsed() >= after => {
                        s.stalled = true;
                        stall
                    }
                    _ => self.service,
                };
                std::thread::sleep(hold);
                s.n += 1;
                s.n - 1
            };
            let (status, text) = (self.answer)(n);
            // Answers as `tre serve` does: its maps carry the scale header.
            let map = if status == 200 {
                "X-Roughness-Scale-M: 0.0001\r\n"
            } else {
                ""
            };
            let resp = format!(
                "HTTP/1.1 {status} X\r\nContent-Type: application/json\r\n{map}Content-Length: {}\r\n\r\n{text}",
                text.len()
            );
            if conn.write_all(resp.as_bytes()).is_err() {
                return;
            }
        }
    }
}

/// 200 "ok" to every request.
pub(crate) fn ok(_: u64) -> (u16, &'static str) {
    (200, "ok")
}

/// One fake frame (the fakes do not read it).
pub(crate) fn frames() -> Frames {
    Frames::from_bytes(vec![b"\x89PNG\r\n\x1a\nnot really".to_vec()], "fake PNG")
}

/// The load of the fake-service runs: `load` for 2 s, 10 s timeout.
pub(crate) fn cfg(load: Load) -> LoadConfig {
    LoadConfig {
        load,
        duration: Some(Duration::from_secs(2)),
        timeout: Duration::from_secs(10),
        ..LoadConfig::default()
    }
}

/// 40 requests a second for 3 s (after 0.5 s of warm-up) over HTTP with the synthetic frame
/// against the service at `url`; started with one worker and a queue of 1, it must refuse most.
pub(crate) fn over_one_worker(url: &str) -> Report {
    let frames = Frames::load(&LoadSource::default()).expect("synthetic frame");
    let target = block_on(Target::resolve(url, false)).expect("loopback target");
    let http = LoadConfig {
        load: Load::Open { rate_per_s: 40.0 },
        duration: Some(Duration::from_secs(3)),
        warmup: Duration::from_millis(500),
        timeout: Duration::from_secs(30),
        ..LoadConfig::default()
    };
    block_on(run_on(&http, &target, &frames)).expect("http load runs")
}
