//! The demo page at `/` in a real browser: starts `tre serve` on a loopback port with the
//! committed models and runs `tests/browser/demo.mjs` (playwright-core driving Debian's
//! headless Chromium) against it: one image through `POST /v1/roughness`, the live stream over
//! the WebSocket, a depth frame's three-state map (with the sensor alone, then with the camera
//! JSON `cameras/real-rgbd_metric3d_nyu.json` as the `camera` part), what each answer says it did
//! (mode, gravity, assumptions), and a bad file's error message.
//!
//! Needs `node`, Chromium (`CHROMIUM`, default `/usr/bin/chromium`) and playwright-core in the
//! browser test's `node_modules` (`tests/browser/setup.sh` installs them). Without
//! them the test prints `skipped: ...` and passes, unless `TRE_REQUIRE_BROWSER=1` (as in CI).

use crate::common;

use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};

use common::{real, repo_root, Server};

/// What the browser test needs and this machine lacks, if anything.
fn missing_prerequisite() -> Option<String> {
    let node = Command::new("node")
        .arg("--version")
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .status();
    if !node.is_ok_and(|s| s.success()) {
        return Some("node is not on PATH".into());
    }
    let chromium = std::env::var("CHROMIUM").unwrap_or_else(|_| "/usr/bin/chromium".into());
    if !Path::new(&chromium).exists() {
        return Some(format!("no Chromium at {chromium}"));
    }
    let playwright = repo_root().join("tests/browser/node_modules/playwright-core");
    if !playwright.exists() {
        return Some(format!("{} is missing", playwright.display()));
    }
    None
}

/// The sensor presets the library knows, comma-separated in its order.
fn sensor_presets() -> String {
    tre_core::roughness::noise::SensorPreset::ALL
        .map(tre_core::roughness::noise::SensorPreset::name)
        .join(",")
}

fn image() -> PathBuf {
    real("slambook2_ch7/1.png")
}

#[test]
fn demo_page_renders_roughness_streams_and_shows_errors() {
    if let Some(why) = missing_prerequisite() {
        if std::env::var("TRE_REQUIRE_BROWSER").is_ok_and(|v| v == "1") {
            panic!("TRE_REQUIRE_BROWSER=1 but {why} (run tests/browser/setup.sh)");
        }
        println!("skipped: demo page browser test: {why} (run tests/browser/setup.sh)");
        return;
    }
    crate::common::skip_unless_shared!("data/real-rgbd");
    let server = Server::start(&[]);
    let out = Command::new("node")
        .arg(repo_root().join("tests/browser/demo.mjs"))
        .arg(server.url())
        .arg(image())
        .arg(real("metric3d_nyu/depth/sync_depth_00000.png"))
        .arg(repo_root().join("cameras/real-rgbd_metric3d_nyu.json"))
        // The page's sensor choices must be the library's presets, in order.
        .env("TRE_SENSOR_PRESETS", sensor_presets())
        .output()
        .expect("cannot run node");
    println!("{}", String::from_utf8_lossy(&out.stdout));
    eprintln!("{}", String::from_utf8_lossy(&out.stderr));
    assert!(
        out.status.success(),
        "tests/browser/demo.mjs failed ({})",
        out.status
    );
}

/// The demo page's source, as the server embeds it.
fn demo_html() -> String {
    std::fs::read_to_string(repo_root().join("crates/tre-server/src/demo/index.html"))
        .expect("the demo page")
}

/// Without a browser: the page served at `/` (embedded from this file) has the Camera fields,
/// sends them as the `camera` part, shows what each answer says it did, and no longer assumes
/// a depth unit or a field of view itself.
#[test]
fn demo_page_has_camera_inputs_and_reads_the_answers_assumptions() {
    let html = demo_html();
    // Every parameter a camera file is read for (the sensor is the select below).
    for field in tre::io::CAMERA_KEYS {
        let input = format!("name=\"{field}\"");
        assert!(html.contains(&input), "no camera input {input}");
    }
    assert!(html.contains("<select id=\"cam-sensor\" name=\"sensor\">"));
    for preset in tre::roughness::noise::SensorPreset::ALL.map(|p| p.name()) {
        assert!(
            html.contains(&format!("<option value=\"{preset}\">")),
            "no sensor {preset}"
        );
    }
    assert!(
        html.contains("id=\"camera-file\""),
        "no camera JSON file input"
    );
    assert!(html.contains("1000 = millimetres, 5000 = TUM"));
    assert!(html.contains(r#"["camera", "camera.json", "application/json""#));
    assert!(html.contains("cameraPart(cam.camera)"));
    for header in ["x-tre-mode", "x-tre-gravity", "x-tre-assumed", "warning"] {
        assert!(
            html.contains(&format!("headers.get(\"{header}\")")),
            "the page does not read {header}"
        );
    }
    // The old label that took millimetres and a 60° field of view for granted.
    assert!(!html.contains("PNG in millimetres"));
    assert!(!html.contains("60° field of view)"));
}

/// Without a browser: the page has the Map panel (a canvas drawing a chosen layer of the latest
/// MapUpdate, and a form that fetches a stream's map by its id), decodes `ServerMessage.map` and
/// `Ready.stream_id`, and can ask its own stream for a map (Hello.map, with the sensor).
#[test]
fn demo_page_has_the_map_panel_and_decodes_map_updates() {
    let html = demo_html();
    for id in [
        "id=\"map\"",
        "id=\"map-canvas\"",
        "id=\"map-layer\"",
        "id=\"map-fetch\"",
        "id=\"map-stream-id\"",
        "id=\"map-info\"",
        "id=\"stream-map\"",
        "id=\"stream-id\"",
    ] {
        assert!(html.contains(id), "no element {id}");
    }
    assert!(html.contains("<label for=\"map-stream-id\">"));
    assert!(html.contains("<label for=\"map-layer\">"));
    for layer in [
        "traversal",
        "roughness",
        "elevation",
        "slope",
        "step",
        "score",
    ] {
        assert!(
            html.contains(&format!("<option value=\"{layer}\"")),
            "no map layer option {layer}"
        );
    }
    // Ready.stream_id (field 3) and ServerMessage.map (field 5) are decoded.
    assert!(html.contains("stream_id"));
    assert!(html.contains("streamId: r.string(f, 3)"));
    assert!(html.contains("[1, 2, 3, 4, 5].filter((n) => top.has(n))"));
    assert!(html.contains("function decodeMapUpdate(buf)"));
    assert!(
        html.contains("BigInt.asIntN(bits, v)"),
        "origin_x/y are signed int64"
    );
    // The map of any open stream, by id.
    assert!(html.contains("/v1/streams/"));
    assert!(html.contains("fetch(`/v1/streams/${encodeURIComponent(id)}/map`)"));
    // Hello.map (field 15) with the sensor (Hello.sensor 13, or its coefficients 14).
    assert!(html.contains(".string(13, sensor).doubles(14, sensorSigmaMm)"));
    assert!(html.contains("hello.message(15,"));
    assert!(html.contains("const MAP_REQUEST = { cellM: 0.05, side: 160, sendHz: 2 };"));
    // Self-contained: nothing from another origin.
    assert!(!html.contains("http://") && !html.contains("https://"));
}
