//! The depth modes end to end: `tre client` sends depth with a camera and a sensor, says once
//! what the server ran and assumed, and writes `.npy` for `--format f32` (and with `--record`
//! an MCAP file that an independent reader checks against them); `tre loadtest` drives
//! the depth-only mode over HTTP and the stream.

use super::*;

/// A folder `frames/` with the sample's RGB twice and `depth/` with its depth under the same
/// stems.
fn sample_frames(dir: &Path) -> (PathBuf, PathBuf) {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("samples/tum_fr2_desk");
    let (frames, depth) = (dir.join("frames"), dir.join("depth"));
    std::fs::create_dir_all(&frames).unwrap();
    std::fs::create_dir_all(&depth).unwrap();
    for stem in ["a", "b"] {
        std::fs::copy(root.join("rgb.png"), frames.join(format!("{stem}.png"))).unwrap();
        std::fs::copy(root.join("depth.png"), depth.join(format!("{stem}.png"))).unwrap();
    }
    (frames, depth)
}

/// `tre client` in the geometric mode on `(frames, depth)` with `more` options into `out`: its
/// stderr, once it has succeeded.
fn client(url: &str, (frames, depth): (&Path, &Path), more: &[&str], out: &Path) -> String {
    let o = Command::new(env!("CARGO_BIN_EXE_tre"))
        .args(["client", "--server", url, "--frames"])
        .arg(frames)
        .arg("--depth")
        .arg(depth)
        .args(["--mode", "geometric", "--as-fast-as-results"])
        .args(more)
        .arg("--out")
        .arg(out)
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&o.stderr).into_owned();
    assert!(o.status.success(), "{stderr}");
    stderr
}

/// The recording of two frames: both in and out, the last roughness equal to its `.npy`.
fn check_client_recording(record: &Path, out: &Path) {
    let last = out.join("2_b.npy");
    let last = last.to_str().unwrap();
    check_mcap(
        record,
        &["--kind", "client", "--frames", "2", "--roughness-npy", last],
    );
}

#[test]
fn the_client_sends_depth_and_says_once_what_the_server_ran_and_assumed() {
    let (_one, dir, server) = serve(&[]);
    let (frames, depth) = sample_frames(dir.path());
    let camera = Path::new(env!("CARGO_MANIFEST_DIR")).join("samples/tum_fr2_desk/camera.json");
    let url = format!("http://{}", server.addr);

    // The client: geometric with the sample's camera and a sensor given on the command line.
    let out = dir.path().join("client");
    let record = dir.path().join("client.mcap");
    let o = Command::new(env!("CARGO_BIN_EXE_tre"))
        .args(["client", "--server", &url, "--frames"])
        .arg(&frames)
        .arg("--depth")
        .arg(&depth)
        .arg("--camera")
        .arg(&camera)
        .arg("--record")
        .arg(&record)
        .args([
            "--mode",
            "geometric",
            "--sensor",
            "kinect_v1",
            "--traversal",
        ])
        .args(["--format", "f32", "--as-fast-as-results", "--out"])
        .arg(&out)
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&o.stderr);
    assert!(o.status.success(), "{stderr}");
    // Told once, though two frames came back; nothing assumed.
    assert_eq!(
        stderr.matches("answers: mode geometric").count(),
        1,
        "{stderr}"
    );
    assert!(stderr.contains("gravity estimated; pitch_deg="), "{stderr}");
    assert!(!stderr.contains("assumed"), "{stderr}");
    assert!(
        stderr.contains("maps of 2 frames and frames.csv in"),
        "{stderr}"
    );
    for stem in ["1_a", "2_b"] {
        let npy = std::fs::read(out.join(format!("{stem}.npy"))).unwrap();
        assert!(npy.starts_with(b"\x93NUMPY"), "{stem}.npy is not a .npy");
        assert!(out.join(format!("{stem}_traversal.png")).is_file());
    }
    check_client_recording(&record, &out);

    // Without the camera the server assumes intrinsics and the depth scale: said once.
    let stderr = client(
        &url,
        (&frames, &depth),
        &[],
        &dir.path().join("client-bare"),
    );
    assert_eq!(
        stderr
            .matches("the server assumed intrinsics, depth_scale")
            .count(),
        1,
        "{stderr}"
    );
}

#[test]
fn the_load_tester_drives_the_depth_only_mode_over_http_and_the_stream() {
    let (_one, dir, server) = serve(&[]);
    server.wait_ready();
    let (_, depth) = sample_frames(dir.path());
    let camera = Path::new(env!("CARGO_MANIFEST_DIR")).join("samples/tum_fr2_desk/camera.json");
    let url = format!("http://{}", server.addr);
    // Depth only, with the camera, over HTTP and over the stream.
    for protocol in ["http", "ws"] {
        let json = dir.path().join(format!("{protocol}.json"));
        let o = Command::new(env!("CARGO_BIN_EXE_tre"))
            .args(["loadtest", "--url", &url, "--protocol", protocol])
            .arg("--depth-dir")
            .arg(&depth)
            .arg("--camera")
            .arg(&camera)
            .args(["--requests", "4", "--json"])
            .arg(&json)
            .output()
            .unwrap();
        let stdout = String::from_utf8_lossy(&o.stdout);
        assert!(
            o.status.success(),
            "{protocol}: {stdout}{}",
            String::from_utf8_lossy(&o.stderr)
        );
        assert!(stdout.contains("depth only: 2 files"), "{stdout}");
        let report: serde_json::Value =
            serde_json::from_slice(&std::fs::read(&json).unwrap()).unwrap();
        assert_eq!(report["ok"], 4, "{protocol}: {report}");
    }
    // A query on the URL goes with every request; one the server refuses is an error, counted.
    let o = Command::new(env!("CARGO_BIN_EXE_tre"))
        .args([
            "loadtest",
            "--url",
            &format!("{url}/v1/roughness?normals=ls&mode=geometric"),
        ])
        .arg("--depth-dir")
        .arg(&depth)
        .arg("--camera")
        .arg(&camera)
        .args(["--requests", "2"])
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let o = Command::new(env!("CARGO_BIN_EXE_tre"))
        .args(["loadtest", "--url", &format!("{url}?mode=nonsense")])
        .arg("--depth-dir")
        .arg(&depth)
        .args(["--requests", "2"])
        .output()
        .unwrap();
    let stdout = String::from_utf8_lossy(&o.stdout);
    assert!(
        !o.status.success() && stdout.contains("http 400"),
        "{stdout}"
    );
}
