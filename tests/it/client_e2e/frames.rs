//! Every frame's result comes back and equals `tre infer`; `tre client` writes one PNG and one
//! CSV row per frame (also through the ffmpeg pipe route) and fails when nothing comes back.

use super::*;

use tre::client::FrameResult;

#[test]
fn every_frame_comes_back_equal_to_tre_infer_and_the_cli_writes_them() {
    crate::common::skip_unless_shared!("data/real-rgbd");
    let (_serial, dir, server) = serve(&[]);
    let frames = make_frames(&dir.path().join("frames"));
    server.wait_ready();

    // The library, one frame at a time: nothing is dropped.
    let results = library_results(server.addr, &frames);
    let sequences: Vec<u64> = results.iter().map(|r| r.sequence).collect();
    assert_eq!(sequences, [1, 2, 3, 4], "every frame's result, in order");
    for ((name, path), r) in frames.iter().zip(&results) {
        assert_equals_tre_infer(name, path, r);
    }

    // The CLI: one PNG and one CSV row per frame, equal to the library's maps.
    assert_cli_writes_every_frame(server.addr, dir.path(), &frames, &results);
    assert_video_goes_through_ffmpeg(server.addr, dir.path(), &frames, &results);
    assert_nothing_back_is_a_failure(server.addr, dir.path());
}

/// The frames sent one at a time through the library, and every result in the order it came.
fn library_results(addr: SocketAddr, frames: &[(String, PathBuf)]) -> Vec<FrameResult> {
    rt().block_on(async {
        let session = Session::connect(session_config(addr)).await.unwrap();
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
    })
}

/// A result equals `tre infer` on its frame, value for value, alpha mask included; its decoded
/// map and its times agree with it.
fn assert_equals_tre_infer(name: &str, path: &Path, r: &FrameResult) {
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

/// `tre client --frames`: one PNG and one CSV row per frame, equal to the library's maps.
fn assert_cli_writes_every_frame(
    addr: SocketAddr,
    dir: &Path,
    frames: &[(String, PathBuf)],
    results: &[FrameResult],
) {
    let out = dir.join("cli");
    let status = Command::new(env!("CARGO_BIN_EXE_tre"))
        .args(["client", "--server", &format!("http://{addr}")])
        .arg("--frames")
        .arg(dir.join("frames"))
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
    for (row, ((name, _), r)) in rows.iter().zip(frames.iter().zip(results)) {
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
}

/// A folder holding a stand-in `ffmpeg` that writes the frames' PNGs back to back.
fn fake_ffmpeg(dir: &Path, frames: &[(String, PathBuf)]) -> PathBuf {
    let fake_bin = dir.join("bin");
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
    fake_bin
}

/// Video input goes through `ffmpeg -f image2pipe -vcodec png -`: a stand-in that writes the
/// frames' PNGs back to back checks the pipe's splitting and naming; without `ffmpeg` on PATH,
/// one clear error line, before connecting.
fn assert_video_goes_through_ffmpeg(
    addr: SocketAddr,
    dir: &Path,
    frames: &[(String, PathBuf)],
    results: &[FrameResult],
) {
    let fake_bin = fake_ffmpeg(dir, frames);
    let video = dir.join("drive.mp4");
    std::fs::write(&video, b"stand-in").unwrap();
    let client = |path_var: &Path, out: &Path| {
        Command::new(env!("CARGO_BIN_EXE_tre"))
            .args(["client", "--server", &addr.to_string(), "--limit", "2"])
            .args(["--mode", "rgb", "--video"])
            .arg(&video)
            .arg("--out")
            .arg(out)
            .env("PATH", path_var)
            .output()
            .unwrap()
    };
    let out = dir.join("video");
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
    let run = client(&dir.join("frames"), &dir.join("none"));
    let stderr = String::from_utf8_lossy(&run.stderr);
    assert!(!run.status.success());
    assert!(
        stderr.contains("needs the `ffmpeg` executable on PATH"),
        "{stderr}"
    );
}

/// Nothing back (every frame is refused): a non-zero exit and the reason.
fn assert_nothing_back_is_a_failure(addr: SocketAddr, dir: &Path) {
    let junk = dir.join("junk");
    std::fs::create_dir_all(&junk).unwrap();
    std::fs::write(junk.join("broken.png"), b"\x89PNG\r\n\x1a\n but not really").unwrap();
    let run = Command::new(env!("CARGO_BIN_EXE_tre"))
        .args(["client", "--server", &addr.to_string(), "--frames"])
        .arg(&junk)
        .arg("--out")
        .arg(dir.join("junk-out"))
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&run.stderr);
    assert!(!run.status.success());
    assert!(stderr.contains("no results came back"), "{stderr}");
    let csv = std::fs::read_to_string(dir.join("junk-out/frames.csv")).unwrap();
    assert!(
        csv.lines().nth(1).unwrap().ends_with(",error:bad_image"),
        "{csv}"
    );
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
