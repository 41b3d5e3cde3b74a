//! The demo page at `/` in a real browser: starts `tre serve` on a loopback port with the
//! committed models and runs `tests/browser/demo.mjs` (playwright-core driving Debian's
//! headless Chromium) against it: one image through `POST /v1/roughness`, the live stream over
//! the WebSocket, a depth frame's three-state map, and a bad file's error message.
//!
//! Needs `node`, Chromium (`CHROMIUM`, default `/usr/bin/chromium`) and
//! `tests/browser/node_modules/playwright-core` (`tests/browser/setup.sh` installs them). Without
//! them the test prints `skipped: ...` and passes, unless `TRE_REQUIRE_BROWSER=1` (as in CI).

use crate::common;

use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};

use common::{real, Server};

fn root() -> &'static Path {
    Path::new(env!("CARGO_MANIFEST_DIR"))
}

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
    let playwright = root().join("tests/browser/node_modules/playwright-core");
    if !playwright.exists() {
        return Some(format!("{} is missing", playwright.display()));
    }
    None
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
    let server = Server::start(&[]);
    let out = Command::new("node")
        .arg(root().join("tests/browser/demo.mjs"))
        .arg(server.url())
        .arg(image())
        .arg(real("metric3d_nyu/depth/sync_depth_00000.png"))
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
