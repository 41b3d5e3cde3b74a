//! The streaming client against the real `tre serve` binary over loopback: every frame's result
//! comes back and equals `tre infer` on the same frame, value for value, alpha mask included;
//! `tre client` writes one PNG and one CSV row per frame (also through the ffmpeg pipe route,
//! with a stand-in `ffmpeg`), and fails when nothing comes back; a session whose server is
//! killed reports the frame in flight lost, reconnects to a new server on the same port and
//! carries on.
#![allow(clippy::unwrap_used)] // Test helpers fail loudly by design.

use crate::common;

use std::io::{BufRead, BufReader};
use std::net::{SocketAddr, TcpListener};
use std::path::{Path, PathBuf};
use std::process::{Child, ChildStdout, Command, Stdio};
use std::sync::Mutex;
use std::time::{Duration, Instant};

use common::{get, infer_png16, png16_values, real};
use image::DynamicImage;
use tre::client::{ClientConfig, Event, Frame, LostReason, Rate, Session};
use tre::pipeline::{Mode, NormalsMethod};

/// One test at a time: each starts servers, and the machine has few cores.
static SERIAL: Mutex<()> = Mutex::new(());

/// A `tre serve` child process at a chosen address (so that a second one can take the first's
/// port), killed on drop; its log goes to a file.
struct Server {
    child: Child,
    addr: SocketAddr,
    log: PathBuf,
    _stdout: BufReader<ChildStdout>,
}

impl Server {
    /// Starts `tre serve --addr ADDR --workers 1` and reads the address it listens on.
    fn start(addr: &str, log: &Path) -> Self {
        Self::start_with(addr, log, &[])
    }

    /// [`Server::start`] with more options.
    fn start_with(addr: &str, log: &Path, more: &[&str]) -> Self {
        let models = Path::new(env!("CARGO_MANIFEST_DIR")).join("models");
        let mut child = Command::new(env!("CARGO_BIN_EXE_tre"))
            .args([
                "serve",
                "--addr",
                addr,
                "--workers",
                "1",
                "--ort-threads",
                "1",
            ])
            .args(more)
            .arg("--models")
            .arg(models)
            .stdout(Stdio::piped())
            .stderr(std::fs::File::create(log).unwrap())
            .spawn()
            .unwrap();
        let mut stdout = BufReader::new(child.stdout.take().unwrap());
        let mut line = String::new();
        stdout.read_line(&mut line).unwrap();
        let Some(url) = line.trim().strip_prefix("listening on http://") else {
            let _ = child.kill();
            panic!(
                "no listening line: {line:?}; log: {}",
                std::fs::read_to_string(log).unwrap_or_default()
            );
        };
        Self {
            addr: url.parse().unwrap(),
            child,
            log: log.to_owned(),
            _stdout: stdout,
        }
    }

    /// Polls `GET /readyz` until it answers 200.
    fn wait_ready(&self) {
        let start = Instant::now();
        while start.elapsed() < Duration::from_secs(300) {
            if get(self.addr, "/readyz").0 == 200 {
                return;
            }
            std::thread::sleep(Duration::from_millis(200));
        }
        panic!(
            "not ready after 300 s; log: {}",
            std::fs::read_to_string(&self.log).unwrap_or_default()
        );
    }

    fn kill(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

impl Drop for Server {
    fn drop(&mut self) {
        self.kill();
    }
}

/// Small frames (160×120 PNGs) made from the real Kinect frames in `../shared/data/real-rgbd`.
fn make_frames(dir: &Path) -> Vec<(String, PathBuf)> {
    let sources = [
        ("a_ch7_1", real("slambook2_ch7/1.png")),
        ("b_ch5_3", real("slambook2_ch5/color/3.png")),
        ("c_nyu_50", real("metric3d_nyu/rgb/rgb_00050.jpg")),
        ("d_ch7_2", real("slambook2_ch7/2.png")),
    ];
    std::fs::create_dir_all(dir).unwrap();
    sources
        .iter()
        .map(|(name, src)| {
            let img = image::open(src).unwrap().to_rgb8();
            let small =
                image::imageops::resize(&img, 160, 120, image::imageops::FilterType::Triangle);
            let path = dir.join(format!("{name}.png"));
            tre::io::save(&path, &DynamicImage::ImageRgb8(small)).unwrap();
            ((*name).to_owned(), path)
        })
        .collect()
}

fn rt() -> tokio::runtime::Runtime {
    tokio::runtime::Builder::new_multi_thread()
        .worker_threads(2)
        .enable_all()
        .build()
        .unwrap()
}

fn session_config(addr: SocketAddr) -> ClientConfig {
    ClientConfig {
        server: format!("ws://{addr}/v1/stream"),
        mode: Some(Mode::Rgb),
        seed: 0,
        normals: Some(NormalsMethod::Dsac),
        rate: Rate::AsFastAsResults,
        frame_timeout: Duration::from_secs(120),
        ..ClientConfig::default()
    }
}

/// The next event, failing the test after two minutes of silence.
async fn next(events: &mut tre::client::Events) -> Event {
    tokio::time::timeout(Duration::from_secs(120), events.recv())
        .await
        .expect("no event within 120 s")
        .expect("the session ended early")
}

#[test]
fn every_frame_comes_back_equal_to_tre_infer_and_the_cli_writes_them() {
    let _serial = SERIAL
        .lock()
        .unwrap_or_else(std::sync::PoisonError::into_inner);
    let dir = tempfile::tempdir().unwrap();
    let frames = make_frames(&dir.path().join("frames"));
    let server = Server::start("127.0.0.1:0", &dir.path().join("serve.log"));
    server.wait_ready();

    // The library, one frame at a time: nothing is dropped.
    let results = rt().block_on(async {
        let session = Session::connect(session_config(server.addr)).await.unwrap();
        assert!(session.server().models.iter().any(|m| m == "depth_net"));
        let (mut sender, mut events) = session.split();
        let paths: Vec<PathBuf> = frames.iter().map(|(_, p)| p.clone()).collect();
        let sending = tokio::spawn(async move {
            let mut sequences = Vec::new();
            for p in paths {
                let png = std::fs::read(p).unwrap();
                sequences.push(sender.send(Frame::rgb(png)).await.unwrap());
            }
            sequences
        });
        let mut results = Vec::new();
        while let Some(ev) = events.recv().await {
            match ev {
                Event::Result(r) => results.push(*r),
                other => panic!("unexpected {other:?}"),
            }
        }
        assert_eq!(sending.await.unwrap(), [1, 2, 3, 4]);
        results
    });
    let sequences: Vec<u64> = results.iter().map(|r| r.sequence).collect();
    assert_eq!(sequences, [1, 2, 3, 4], "every frame's result, in order");

    for ((name, path), r) in frames.iter().zip(&results) {
        let args = [
            path.to_str().unwrap(),
            "--mode",
            "rgb",
            "--normals",
            "dsac",
            "--seed",
            "0",
        ];
        let want = infer_png16(&args);
        assert_eq!((r.width, r.height), (160, 120));
        let got = png16_values(&r.encoded);
        assert_eq!((got.0, got.1), (want.0, want.1));
        let differ = got.2.iter().zip(&want.2).filter(|(a, b)| a != b).count();
        assert_eq!(
            differ, 0,
            "{name}: {differ} grey/alpha values differ from tre infer"
        );
        let pixels: Vec<&[u16]> = want.2.chunks_exact(2).collect();
        let valid = pixels.iter().filter(|p| p[1] == u16::MAX).count();
        let holes = pixels.iter().filter(|p| p[1] == 0).count();
        assert!(valid > 0, "{name}: no roughness at all");
        assert_eq!(holes + valid, 160 * 120, "{name}: alpha is 0 or 65535");
        // The decoded grid is the same map in metres, NaN where alpha is 0.
        let m = r.roughness_m().unwrap();
        for (v, p) in m.as_slice().iter().zip(&pixels) {
            if p[1] == 0 {
                assert!(v.is_nan());
            } else {
                assert_eq!(*v, f64::from(p[0]) * tre::io::ROUGHNESS_PNG_SCALE_M);
            }
        }
        assert!(
            r.latency >= r.server_latency,
            "{name}: round trip ≥ server time"
        );
        assert_spans_latency(
            r.sent_unix_us,
            r.received_unix_us,
            r.latency.as_secs_f64() * 1e3,
        );
        assert!(!r.timings.is_empty());
    }

    // The CLI: one PNG and one CSV row per frame, equal to the library's maps.
    let out = dir.path().join("cli");
    let status = Command::new(env!("CARGO_BIN_EXE_tre"))
        .args(["client", "--server", &format!("http://{}", server.addr)])
        .arg("--frames")
        .arg(dir.path().join("frames"))
        .args(["--as-fast-as-results", "--mode", "rgb", "--normals", "dsac"])
        .args(["--seed", "0", "--out"])
        .arg(&out)
        .stderr(Stdio::null())
        .status()
        .unwrap();
    assert!(status.success());
    let csv = std::fs::read_to_string(out.join("frames.csv")).unwrap();
    let mut lines = csv.lines();
    assert_eq!(
        lines.next(),
        Some("sequence,name,send_unix_us,receive_unix_us,latency_ms,server_latency_ms,dropped,status")
    );
    let rows: Vec<Vec<&str>> = lines.map(|l| l.split(',').collect()).collect();
    assert_eq!(rows.len(), frames.len(), "{csv}");
    for (row, ((name, _), r)) in rows.iter().zip(frames.iter().zip(&results)) {
        assert_eq!(row.len(), 8, "{row:?}");
        assert_eq!(
            (row[1], row[6], row[7]),
            (name.as_str(), "0", "ok"),
            "{row:?}"
        );
        let seq = row[0];
        let (sent, received): (i64, i64) = (row[2].parse().unwrap(), row[3].parse().unwrap());
        let latency: f64 = row[4].parse().unwrap();
        assert_spans_latency(sent, received, latency);
        let server_latency: f64 = row[5].parse().unwrap();
        assert!(latency >= server_latency && server_latency > 0.0, "{row:?}");
        let written = std::fs::read(out.join(format!("{seq}_{name}.png"))).unwrap();
        assert_eq!(
            png16_values(&written),
            png16_values(&r.encoded),
            "{seq}_{name}.png"
        );
    }

    // Video input goes through `ffmpeg -f image2pipe -vcodec png -`: a stand-in that writes
    // the frames' PNGs back to back checks the pipe's splitting and naming.
    let fake_bin = dir.path().join("bin");
    std::fs::create_dir_all(&fake_bin).unwrap();
    let pngs: Vec<String> = frames
        .iter()
        .map(|(_, p)| p.display().to_string())
        .collect();
    let script = format!("#!/bin/sh\ncat {}\n", pngs.join(" "));
    std::fs::write(fake_bin.join("ffmpeg"), script).unwrap();
    #[cfg(unix)]
    {
        use std::os::unix::fs::PermissionsExt;
        let exe = std::fs::Permissions::from_mode(0o755);
        std::fs::set_permissions(fake_bin.join("ffmpeg"), exe).unwrap();
    }
    let video = dir.path().join("drive.mp4");
    std::fs::write(&video, b"stand-in").unwrap();
    let client = |path_var: &Path, out: &Path| {
        Command::new(env!("CARGO_BIN_EXE_tre"))
            .args([
                "client",
                "--server",
                &server.addr.to_string(),
                "--limit",
                "2",
            ])
            .args(["--mode", "rgb", "--video"])
            .arg(&video)
            .arg("--out")
            .arg(out)
            .env("PATH", path_var)
            .output()
            .unwrap()
    };
    let out = dir.path().join("video");
    let mut path_var = fake_bin.clone().into_os_string();
    path_var.push(":");
    path_var.push(std::env::var_os("PATH").unwrap_or_default());
    let run = client(Path::new(&path_var), &out);
    assert!(
        run.status.success(),
        "{}",
        String::from_utf8_lossy(&run.stderr)
    );
    for (seq, r) in results.iter().take(2).enumerate() {
        let written = out.join(format!("{}_drive_{:06}.png", seq + 1, seq + 1));
        assert_eq!(
            png16_values(&std::fs::read(&written).unwrap()),
            png16_values(&r.encoded)
        );
    }
    assert_eq!(
        std::fs::read_to_string(out.join("frames.csv"))
            .unwrap()
            .lines()
            .count(),
        3
    );
    // Without ffmpeg on PATH: one clear error line, before connecting.
    let run = client(&dir.path().join("frames"), &dir.path().join("none"));
    let stderr = String::from_utf8_lossy(&run.stderr);
    assert!(!run.status.success());
    assert!(
        stderr.contains("needs the `ffmpeg` executable on PATH"),
        "{stderr}"
    );

    // Nothing back (every frame is refused): a non-zero exit and the reason.
    let junk = dir.path().join("junk");
    std::fs::create_dir_all(&junk).unwrap();
    std::fs::write(junk.join("broken.png"), b"\x89PNG\r\n\x1a\n but not really").unwrap();
    let run = Command::new(env!("CARGO_BIN_EXE_tre"))
        .args(["client", "--server", &server.addr.to_string(), "--frames"])
        .arg(&junk)
        .arg("--out")
        .arg(dir.path().join("junk-out"))
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&run.stderr);
    assert!(!run.status.success());
    assert!(stderr.contains("no results came back"), "{stderr}");
    let csv = std::fs::read_to_string(dir.path().join("junk-out/frames.csv")).unwrap();
    assert!(
        csv.lines().nth(1).unwrap().ends_with(",error:bad_image"),
        "{csv}"
    );
}

#[test]
fn a_session_reconnects_to_a_restarted_server_and_carries_on() {
    let _serial = SERIAL
        .lock()
        .unwrap_or_else(std::sync::PoisonError::into_inner);
    let dir = tempfile::tempdir().unwrap();
    let frames = make_frames(&dir.path().join("frames"));
    let png = |i: usize| std::fs::read(&frames[i].1).unwrap();
    let port = TcpListener::bind("127.0.0.1:0")
        .unwrap()
        .local_addr()
        .unwrap()
        .port();
    let addr = format!("127.0.0.1:{port}");
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
        match next(&mut events).await {
            Event::Reconnected {
                attempts, server, ..
            } => {
                assert!(attempts >= 1);
                assert!(server.models.iter().any(|m| m == "depth_net"));
            }
            other => panic!("expected Reconnected, got {other:?}"),
        }
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

/// The send and receive times (µs since the epoch, wall clock) are the ends of the latency
/// (ms, monotonic clock): within a few µs of rounding and the two clocks' reads, and 0.1% for a
/// wall clock being slewed.
fn assert_spans_latency(sent_us: i64, received_us: i64, latency_ms: f64) {
    let span_ms = (received_us - sent_us) as f64 / 1e3;
    assert!(
        (span_ms - latency_ms).abs() <= 0.05 + 1e-3 * latency_ms,
        "received − sent = {span_ms} ms, latency {latency_ms} ms"
    );
}

/// A server that stops mid-stream (SIGSTOP: hung, with its socket open) once froze the client:
/// once the frames filled the connection, the write in progress blocked the whole session, so
/// no frame was reported lost, the silence check never ran and the client never reconnected,
/// for as long as the server stayed stopped. Now frames time out on time, the silence drops the
/// connection, and the session carries on once the server answers again.
#[test]
fn a_hung_server_is_reported_on_time_and_the_session_recovers() {
    let _serial = SERIAL
        .lock()
        .unwrap_or_else(std::sync::PoisonError::into_inner);
    let dir = tempfile::tempdir().unwrap();
    let mut server = Server::start("127.0.0.1:0", &dir.path().join("serve.log"));
    server.wait_ready();
    // 1200×1200 of noise: a 4.3 MB PNG, so that a few fill the socket buffers.
    let noise = {
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
    };
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
        let (mut first_lost, mut disconnected) = (None, None);
        while disconnected.is_none() && stopped.elapsed() < Duration::from_secs(20) {
            let wait = Duration::from_secs(20).saturating_sub(stopped.elapsed());
            match tokio::time::timeout(wait, events.recv()).await {
                Ok(Some(Event::Lost { reason, .. })) if first_lost.is_none() => {
                    assert_eq!(reason, LostReason::TimedOut);
                    first_lost = Some(stopped.elapsed());
                }
                Ok(Some(Event::Disconnected { reason })) => {
                    assert!(reason.contains("nothing heard"), "{reason}");
                    disconnected = Some(stopped.elapsed());
                }
                Ok(Some(_)) => {}
                Ok(None) | Err(_) => break,
            }
        }
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
    use std::io::{Read, Write};
    let _serial = SERIAL
        .lock()
        .unwrap_or_else(std::sync::PoisonError::into_inner);
    let dir = tempfile::tempdir().unwrap();
    make_frames(&dir.path().join("frames"));
    let more = ["--max-connections", "1", "--request-timeout-ms", "60000"];
    let server = Server::start_with("127.0.0.1:0", &dir.path().join("server.log"), &more);
    server.wait_ready();
    // A kept-alive connection, seen served, holds the only place for 3 s.
    let holder = loop {
        let mut tcp = std::net::TcpStream::connect(server.addr).unwrap();
        tcp.write_all(b"GET /healthz HTTP/1.1\r\nHost: x\r\n\r\n")
            .unwrap();
        let mut buf = [0u8; 512];
        let n = tcp.read(&mut buf).unwrap();
        if buf[..n].starts_with(b"HTTP/1.1 200") {
            break tcp;
        }
        std::thread::sleep(Duration::from_millis(50));
    };
    let release = std::thread::spawn(move || {
        std::thread::sleep(Duration::from_secs(3));
        drop(holder);
    });
    let out = dir.path().join("out");
    let start = Instant::now();
    let mut child = Command::new(env!("CARGO_BIN_EXE_tre"))
        .args([
            "client",
            "--server",
            &format!("ws://{}/v1/stream", server.addr),
        ])
        .arg("--frames")
        .arg(dir.path().join("frames"))
        .args(["--as-fast-as-results", "--mode", "rgb", "--normals", "ls"])
        .args(["--limit", "2", "--reconnect-initial-ms", "200"])
        .args(["--reconnect-max-ms", "1000", "--out"])
        .arg(&out)
        .stderr(Stdio::piped())
        .stdout(Stdio::null())
        .spawn()
        .unwrap();
    let mut stderr = child.stderr.take().unwrap();
    let reader = std::thread::spawn(move || {
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

/// A CA and a certificate for `localhost` it issued, made here: (CA PEM, server chain, key).
fn test_pki() -> (
    String,
    Vec<rustls::pki_types::CertificateDer<'static>>,
    rustls::pki_types::PrivateKeyDer<'static>,
) {
    let ca_key = rcgen::KeyPair::generate().unwrap();
    let mut ca_params = rcgen::CertificateParams::new(Vec::<String>::new()).unwrap();
    ca_params.is_ca = rcgen::IsCa::Ca(rcgen::BasicConstraints::Unconstrained);
    ca_params
        .distinguished_name
        .push(rcgen::DnType::CommonName, "tre test CA");
    let ca = ca_params.self_signed(&ca_key).unwrap();
    let issuer = rcgen::Issuer::new(ca_params, ca_key);
    let key = rcgen::KeyPair::generate().unwrap();
    let leaf = rcgen::CertificateParams::new(vec!["localhost".to_owned()])
        .unwrap()
        .signed_by(&key, &issuer)
        .unwrap();
    let chain = vec![leaf.der().clone(), ca.der().clone()];
    let key = rustls::pki_types::PrivateKeyDer::Pkcs8(key.serialize_der().into());
    (ca.pem(), chain, key)
}

/// A TLS-terminating proxy on a loopback port in front of `upstream` (as Caddy or an Ingress
/// would be), on `rt`: TLS in, the plain bytes forwarded. Returns its address and the CA's PEM.
fn tls_proxy(rt: &tokio::runtime::Runtime, upstream: SocketAddr) -> (SocketAddr, String) {
    let (ca_pem, chain, key) = test_pki();
    let provider = std::sync::Arc::new(rustls::crypto::ring::default_provider());
    let config = rustls::ServerConfig::builder_with_provider(provider)
        .with_safe_default_protocol_versions()
        .unwrap()
        .with_no_client_auth()
        .with_single_cert(chain, key)
        .unwrap();
    let acceptor = tokio_rustls::TlsAcceptor::from(std::sync::Arc::new(config));
    let listener = rt
        .block_on(tokio::net::TcpListener::bind("127.0.0.1:0"))
        .unwrap();
    let addr = listener.local_addr().unwrap();
    rt.spawn(async move {
        while let Ok((tcp, _)) = listener.accept().await {
            let acceptor = acceptor.clone();
            tokio::spawn(async move {
                let Ok(mut tls) = acceptor.accept(tcp).await else {
                    return;
                };
                let Ok(mut plain) = tokio::net::TcpStream::connect(upstream).await else {
                    return;
                };
                let _ = tokio::io::copy_bidirectional(&mut tls, &mut plain).await;
            });
        }
    });
    (addr, ca_pem)
}

/// `tre client` and `tre loadtest` over TLS: through a TLS-terminating proxy in front of a
/// `tre serve` with an API key, with the proxy's private CA given by `--ca-cert`, the stream
/// (`wss://`) and HTTP (`https://`) both work and carry the key; without the CA the
/// certificate is refused and the error says so.
#[test]
fn the_client_and_the_load_tester_speak_tls_to_a_proxy_with_a_private_ca() {
    let _serial = SERIAL
        .lock()
        .unwrap_or_else(std::sync::PoisonError::into_inner);
    let dir = tempfile::tempdir().unwrap();
    let frames = make_frames(&dir.path().join("frames"));
    let key = "tls-test-key-0123456789";
    let server = Server::start_with(
        "127.0.0.1:0",
        &dir.path().join("server.log"),
        &["--api-key", key],
    );
    server.wait_ready();
    let rt = rt();
    let (proxy, ca_pem) = tls_proxy(&rt, server.addr);
    let ca = dir.path().join("ca.pem");
    std::fs::write(&ca, ca_pem).unwrap();
    let tre = |args: &[&str]| {
        Command::new(env!("CARGO_BIN_EXE_tre"))
            .args(args)
            .env("TRE_API_KEY", key)
            .output()
            .unwrap()
    };
    let wss = format!("wss://localhost:{}/v1/stream", proxy.port());
    let out = dir.path().join("out");
    let frames_dir = dir.path().join("frames");
    let client = |extra: &[&str]| {
        let mut args = vec!["client", "--server", &wss, "--frames"];
        args.push(frames_dir.to_str().unwrap());
        args.extend(["--mode", "rgb", "--normals", "ls", "--limit", "2", "--out"]);
        args.push(out.to_str().unwrap());
        args.extend(extra);
        tre(&args)
    };
    let run = client(&["--ca-cert", ca.to_str().unwrap()]);
    assert!(
        run.status.success(),
        "{}",
        String::from_utf8_lossy(&run.stderr)
    );
    let csv = std::fs::read_to_string(out.join("frames.csv")).unwrap();
    assert_eq!(
        csv.lines().filter(|l| l.ends_with(",ok")).count(),
        2,
        "{csv}"
    );

    // Without the private CA: refused on the certificate, named, without retrying for long.
    let run = client(&["--reconnect-attempts", "1"]);
    let stderr = String::from_utf8_lossy(&run.stderr);
    assert!(!run.status.success());
    assert!(
        stderr.contains("certificate") || stderr.contains("UnknownIssuer"),
        "{stderr}"
    );

    // The load tester, over https:// and over the stream (wss://).
    let https = format!("https://localhost:{}", proxy.port());
    let frame = frames[0].1.to_str().unwrap();
    for protocol in ["http", "ws"] {
        let json = dir.path().join(format!("load-{protocol}.json"));
        let run = tre(&[
            "loadtest",
            "--url",
            &https,
            "--ca-cert",
            ca.to_str().unwrap(),
            "--protocol",
            protocol,
            "--requests",
            "3",
            "--frame",
            frame,
            "--json",
            json.to_str().unwrap(),
        ]);
        assert!(
            run.status.success(),
            "{protocol}: {}{}",
            String::from_utf8_lossy(&run.stdout),
            String::from_utf8_lossy(&run.stderr)
        );
        let report: serde_json::Value =
            serde_json::from_slice(&std::fs::read(&json).unwrap()).unwrap();
        assert_eq!(report["ok"], 3, "{protocol}: {report}");
    }
}
