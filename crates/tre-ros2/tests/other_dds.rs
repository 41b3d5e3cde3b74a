//! The node against ROS 2 peers of other DDS implementations at their stock settings
//! (`scripts/ros2_rates.py`): they publish real kitchen depth frames, camera_info and odometry
//! and subscribe to the node's outputs with ROS 2's default subscription profile (reliable, keep
//! the last 10). Every message the middleware takes from the node must reach them, with the
//! stamp of its frame (a write it refuses, its reliable window full under load, is counted and
//! logged by the node, and most must be taken):
//!
//! - Eclipse Cyclone DDS (the `cyclonedds` wheel): the roughness, its PNG, the grid map and the
//!   occupancy grid;
//! - a real rclpy node over eProsima Fast DDS, ROS 2's default middleware (the `ros-*` wheels of
//!   ROS 2 Kilted): the roughness's PNG and the occupancy grid, which fit its stock socket
//!   buffer (the raw 1.2 MB roughness does not; docs/ros2.md).
//!
//! Python: `TRE_DDS_PYTHON`, else `.ci/.venv-py` as `.ci/run` makes it (with
//! `scripts/requirements-dds.txt`). Skipped without it or without `../shared`, unless
//! `TRE_REQUIRE_DDS=1` (CI), where a missing peer fails.
#![allow(clippy::unwrap_used, clippy::print_stderr)] // A test fails loudly and prints.

use std::path::{Path, PathBuf};
use std::process::Command;
use std::sync::atomic::Ordering;

use tre_ros2::{NodeConfig, PoseSource, Reliability};

mod common;

fn root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../..")
}

fn required() -> bool {
    std::env::var("TRE_REQUIRE_DDS").is_ok_and(|v| v == "1")
}

/// A Python that imports the peer's packages (`imports`), or why there is none.
fn python(imports: &str) -> Result<PathBuf, String> {
    let py = std::env::var_os("TRE_DDS_PYTHON")
        .filter(|p| !p.is_empty())
        .map_or_else(|| root().join(".ci/.venv-py/bin/python"), PathBuf::from);
    let ok = Command::new(&py)
        .args(["-c", &format!("import {imports}, numpy, PIL")])
        .output()
        .map_err(|e| format!("{}: {e}", py.display()))?;
    if ok.status.success() {
        Ok(py)
    } else {
        Err(format!(
            "{} cannot import {imports}, numpy and PIL (scripts/requirements-dds.txt): {}",
            py.display(),
            String::from_utf8_lossy(&ok.stderr)
        ))
    }
}

/// The node under test on `domain`: kinect_v1 noise, the indoor map from `/odom`.
fn start_node(dir: &Path, domain: u16) -> tre_ros2::RunningNode {
    let processor = common::kinect_processor(common::indoor_map(dir));
    tre_ros2::start(
        NodeConfig {
            domain_id: domain,
            pose: Some(PoseSource::Odometry("/odom".into())),
            // Reliable in as well, so that every frame sent is a frame received.
            input_reliability: Reliability::Reliable,
            ..NodeConfig::default()
        },
        processor,
    )
    .unwrap()
}

/// The peer's report and the node's counts.
struct Run {
    report: serde_json::Value,
    received: u64,
    published: u64,
    fused: u64,
    grids: u64,
    /// Messages the middleware took, by topic.
    written: std::collections::BTreeMap<&'static str, u64>,
}

/// The peer's Python (importing `imports`) and the kitchen frames; `None` (skipped) without
/// either, unless required.
fn peer_and_frames(imports: &str) -> Option<(PathBuf, PathBuf)> {
    match (python(imports), common::kitchen_dir()) {
        (Ok(py), Some(dir)) => Some((py, dir)),
        (py, dir) => {
            let why = format!(
                "{} {}",
                py.err().unwrap_or_default(),
                if dir.is_none() { "no ../shared" } else { "" }
            );
            assert!(!required(), "TRE_REQUIRE_DDS=1 but {why}");
            eprintln!("skipped: {why}");
            None
        }
    }
}

/// Runs the node and the `dds` peer (importing `imports`) subscribed to `topics`; `None`
/// (skipped) without the peer or the frames.
fn run(dds: &str, imports: &str, domain: u16, topics: &str) -> Option<Run> {
    let (py, dir) = peer_and_frames(imports)?;
    let node = start_node(&dir, domain);
    let out = Command::new(&py)
        .arg(root().join("scripts/ros2_rates.py"))
        .args([
            "--dds",
            dds,
            "--domain",
            &domain.to_string(),
            "--subscribe",
            topics,
        ])
        .arg("--frames")
        .arg(&dir)
        .args(["--count", "15", "--step", "5", "--hz", "5", "--reliability"])
        .arg("reliable")
        .output()
        .unwrap();
    let stats = node.stats();
    let count = |c: &std::sync::atomic::AtomicU64| c.load(Ordering::Relaxed);
    let (received, published, fused, grids, unsent) = (
        count(&stats.received),
        count(&stats.published),
        count(&stats.fused),
        count(&stats.grids),
        count(&stats.unsent),
    );
    let written = stats.written.lock().unwrap().clone();
    drop(node.stop());
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "the {dds} peer failed: {stderr}");
    let report: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    eprintln!(
        "{report}\nnode: received {received}, published {published}, fused {fused}, \
         written {written:?}, refused by the middleware {unsent}"
    );
    assert_eq!(
        received, 15,
        "the node received {received} of 15 depth frames"
    );
    assert!(published > 0 && fused > 0, "nothing published: {report}");
    Some(Run {
        report,
        received,
        published,
        fused,
        grids,
        written,
    })
}

impl Run {
    fn got(&self, topic: &str) -> u64 {
        self.report["topics"][topic]["received"]
            .as_u64()
            .unwrap_or(0)
    }

    /// Every message the middleware took on `topic` reached the peer, and it took most of
    /// `made` (one refused under load is logged and replaced by the next frame's).
    fn all_delivered(&self, topic: &str, made: u64) {
        let written = self.written.get(topic).copied().unwrap_or(0);
        assert_eq!(self.got(topic), written, "{topic}: {}", self.report);
        assert!(
            written > 0 && 2 * written > made,
            "{topic}: the middleware took {written} of {made}: {}",
            self.report
        );
    }
}

#[test]
fn every_published_message_reaches_a_stock_cyclone_dds_subscriber() {
    let domain = 60 + (std::process::id() % 40) as u16 * 2;
    let topics = "roughness,roughness/compressed,grid_map,occupancy";
    let Some(r) = run("cyclone", "cyclonedds", domain, topics) else {
        return;
    };
    assert_eq!(r.received, 15);
    assert_eq!(
        r.grids, r.fused,
        "a grid map for every fused frame (grid period 0)"
    );
    for (topic, made) in [
        ("roughness", r.published),
        ("roughness/compressed", r.published),
        ("grid_map", r.grids),
        ("occupancy", r.fused),
    ] {
        r.all_delivered(topic, made);
    }
}

#[test]
fn the_roughness_png_and_the_occupancy_grid_reach_a_stock_rclpy_fast_dds_subscriber() {
    let domain = 61 + (std::process::id() % 40) as u16 * 2;
    let topics = "roughness/compressed,occupancy";
    let Some(r) = run("fastdds", "rclpy, sensor_msgs, nav_msgs", domain, topics) else {
        return;
    };
    r.all_delivered("roughness/compressed", r.published);
    r.all_delivered("occupancy", r.fused);
}
