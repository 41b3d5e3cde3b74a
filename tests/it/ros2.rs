//! `tre ros2` against a second ROS 2 node (ros2-client, no ROS installation): the kitchen
//! sequence's real depth frames, camera_info and poses in; roughness images and a grid map out,
//! equal to `tre infer` and `tre map` on the same frames; bad input skipped while the node keeps
//! running; the recording read back by the Python `mcap` reader.
//!
//! RustDDS finds its peers by multicast on a multicast-capable interface (not loopback): each
//! test has a domain id of its own, and when no peer is found the test fails saying what the
//! machine lacks.
#![allow(clippy::unwrap_used)] // Test helpers fail loudly by design.

use std::path::Path;
use std::process::Command;
use std::time::Duration;

use tre::record::msgs::GridMap;

use crate::common::{check_mcap, npy_f32};

mod kitchen;
mod node;
mod peer;
mod references;

use kitchen::{depth_msg, header, info_msg, kitchen, pose_msg, stamp, Kitchen};
use node::{assert_no_errors_at_stop, assert_quiet_while_running, start_tre, stop_tre};
use peer::{domain_id, take_stamped, Peer};
use references::{
    assert_occupancy_is_traversal, f32_values, grid_layer, infer_npy, map_sequence, run_tre_map,
    same_bits,
};

/// Frame `i` through the node: its roughness equal to `tre infer`'s, its three-state image,
/// and the map after it; the frame and its pose also go into `tre map`'s sequence `seq`.
fn send_and_check(
    peer: &Peer,
    k: &Kitchen,
    i: usize,
    stem: &str,
    dir: &Path,
    seq: &Path,
) -> GridMap {
    let depth_path = k.dir.join(format!("depth/{stem}.png"));
    std::fs::copy(&depth_path, seq.join(format!("depth/{stem}.png"))).unwrap();
    // `tre map`'s poses: after the node's quaternion round trip.
    let (pose, text) = pose_msg(k, stem);
    std::fs::write(seq.join(format!("poses/{stem}.txt")), text).unwrap();
    let roughness = peer.send(i, &depth_path, Some(pose));
    assert_eq!(roughness.header, header(i));
    let traversal = take_stamped(&peer.traversal, stamp(i), Duration::from_secs(5), |m| {
        &m.header
    })
    .unwrap();
    assert_eq!(
        (traversal.encoding.as_str(), traversal.width),
        ("mono8", 640)
    );
    let grid = take_stamped(&peer.grid, stamp(i), Duration::from_secs(5), |m| &m.header).unwrap();
    // The same frame through `tre infer`.
    let npy = dir.join(format!("{stem}.npy"));
    infer_npy(&depth_path, &k.camera, &npy);
    assert!(
        same_bits(&f32_values(&roughness), &npy_f32(&npy).1),
        "{stem}: the node's roughness differs from tre infer's"
    );
    grid
}

#[test]
fn kitchen_frames_through_the_node_equal_infer_and_map() {
    let Some(k) = kitchen(5) else { return };
    let dir = tempfile::tempdir().unwrap();
    let record = dir.path().join("run.mcap");
    let domain = domain_id(0).to_string();
    let gravity = format!(
        "--gravity={:?},{:?},{:?}",
        k.gravity[0], k.gravity[1], k.gravity[2]
    );
    let tre = start_tre(&[
        "--domain-id",
        &domain,
        "--odom-topic",
        "/odom",
        "--sensor",
        "kinect_v1",
        "--publish-traversal",
        "--publish-uncertainty",
        &gravity,
        "--map-frame",
        "world",
        "--record",
        record.to_str().unwrap(),
        "--record-bag",
    ]);
    let peer = Peer::new(domain_id(0));
    peer.wait_for_tre(true);
    let seq = dir.path().join("seq");
    map_sequence(&k, &seq);
    let mut last_grid = None;
    for (i, stem) in k.stems.iter().enumerate() {
        last_grid = Some(send_and_check(&peer, &k, i, stem, dir.path(), &seq));
    }
    let occupancy = take_stamped(&peer.occupancy, stamp(4), Duration::from_secs(5), |m| {
        &m.header
    })
    .unwrap();
    assert_quiet_while_running(&tre, k.stems.len());
    let (ok, stdout, stderr) = stop_tre(tre);
    assert!(ok, "tre ros2 failed: {stderr}");
    assert!(stdout.contains("published 5"), "{stdout}");
    assert_no_errors_at_stop(&stderr);
    // The same frames through `tre map`.
    let out = dir.path().join("map");
    run_tre_map(&seq, &out);
    let grid = last_grid.unwrap();
    assert_eq!(grid.header.frame_id, "world");
    assert_eq!(grid.info.resolution, 0.04);
    for name in tre::map::LAYER_NAMES {
        assert!(
            same_bits(
                &grid_layer(&grid, name),
                &npy_f32(&out.join(format!("{name}.npy"))).1
            ),
            "layer {name}: the node's map differs from tre map's"
        );
    }
    assert_occupancy_is_traversal(&occupancy, &npy_f32(&out.join("traversal.npy")).1);
    check_recording(&record, dir.path());
}

/// The recording decoded by the Python `mcap` and `mcap-ros2-support` packages
/// (scripts/check_mcap.py): schemas, counts and the roughness values against `tre infer`'s;
/// then the bag's `metadata.yaml`.
fn check_recording(record: &Path, dir: &Path) {
    let npy = dir.join("frame-000020.npy");
    check_mcap(
        record,
        &["--frames", "5", "--roughness-npy", npy.to_str().unwrap()],
    );
    check_bag_metadata(dir);
    // `TRE_ROS2_RECORDING_OUT=FILE` keeps the recording (docs/ros2.md's picture is drawn from it).
    if let Some(keep) = std::env::var_os("TRE_ROS2_RECORDING_OUT") {
        std::fs::copy(record, keep).unwrap();
    }
}

/// `--record-bag`: the folder's `metadata.yaml` lists the recording and every CDR topic with
/// its type hash, its QoS and as many messages as the MCAP holds (counted by the Python
/// `mcap` reader when there is one).
fn check_bag_metadata(dir: &Path) {
    let text = std::fs::read_to_string(dir.join("metadata.yaml")).unwrap();
    let y: serde_yaml_ng::Value = serde_yaml_ng::from_str(&text).unwrap();
    let info = &y["rosbag2_bagfile_information"];
    assert_eq!(info["version"].as_u64(), Some(8), "{text}");
    assert_eq!(info["storage_identifier"].as_str(), Some("mcap"), "{text}");
    assert_eq!(info["relative_file_paths"][0].as_str(), Some("run.mcap"));
    let mut listed = std::collections::BTreeMap::new();
    for t in info["topics_with_message_count"].as_sequence().unwrap() {
        let m = &t["topic_metadata"];
        assert_eq!(m["serialization_format"].as_str(), Some("cdr"));
        assert!(m["type_description_hash"]
            .as_str()
            .is_some_and(|h| h.starts_with("RIHS01_") && h.len() == 71));
        assert!(m["offered_qos_profiles"]
            .as_str()
            .is_some_and(|q| q.contains("reliability: 1")));
        let name = m["name"].as_str().unwrap().to_owned();
        listed.insert(name, t["message_count"].as_u64().unwrap());
    }
    assert!(listed.contains_key("/tre/roughness") && listed.contains_key("/odom"));
    let total: u64 = listed.values().sum();
    assert_eq!(info["message_count"].as_u64(), Some(total));
    assert_eq!(listed["/tre/roughness"], 5, "{text}");
    let Ok(python) = std::env::var("TRE_MCAP_PYTHON") else {
        return;
    };
    let script = "import sys, json\nfrom mcap.reader import make_reader\nc = {}\n\
                  for _, ch, _ in make_reader(open(sys.argv[1], 'rb')).iter_messages():\n    \
                  c[ch.topic] = c.get(ch.topic, 0) + 1\nprint(json.dumps(c))\n";
    let o = Command::new(python)
        .args(["-c", script])
        .arg(dir.join("run.mcap"))
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let counted: std::collections::BTreeMap<String, u64> =
        serde_json::from_slice(&o.stdout).unwrap();
    assert_eq!(listed, counted, "metadata.yaml against the MCAP file");
}

#[test]
fn bad_input_is_skipped_and_the_node_recovers() {
    let Some(k) = kitchen(1) else { return };
    let domain = domain_id(1).to_string();
    let tre = start_tre(&["--domain-id", &domain, "--sensor", "kinect_v1"]);
    let peer = Peer::new(domain_id(1));
    peer.wait_for_tre(false);
    let depth_path = k.dir.join(format!("depth/{}.png", k.stems[0]));
    let good = depth_msg(&depth_path, 0);
    let info = info_msg(0, (good.width, good.height));
    // Each bad frame is skipped, and logged, before the next one is sent.
    let logged = |why: &str| {
        assert!(
            tre.wait_for_log(why, Duration::from_secs(30)),
            "{why:?} not logged: {}",
            tre.log.lock().unwrap()
        );
    };
    // 1. No camera_info yet.
    let mut d = good.clone();
    d.header = header(1);
    peer.depth.publish(d.clone()).unwrap();
    logged("no camera_info received yet");
    // 2. A camera_info of another size.
    let mut small = info.clone();
    small.width = 320;
    peer.info.publish(small).unwrap();
    std::thread::sleep(Duration::from_millis(500));
    d.header = header(2);
    peer.depth.publish(d.clone()).unwrap();
    logged("camera_info is 320×480 but the image is 640×480");
    // 3. An encoding the node does not read.
    peer.info.publish(info.clone()).unwrap();
    std::thread::sleep(Duration::from_millis(200));
    let mut bad = d.clone();
    bad.header = header(3);
    bad.encoding = "8UC2".into();
    peer.depth.publish(bad).unwrap();
    logged("encoding \"8UC2\" is not read");
    // 4. Nothing valid.
    let mut empty = d.clone();
    empty.header = header(4);
    empty.data.fill(0);
    peer.depth.publish(empty).unwrap();
    logged("no valid pixel");
    // No output for any of them.
    for i in 1..=4 {
        assert!(take_stamped(&peer.roughness, stamp(i), Duration::ZERO, |m| &m.header).is_none());
    }
    // 5. A good frame: the node recovers.
    assert_eq!(peer.send(5, &depth_path, None).header, header(5));
    let (exit_ok, stdout, stderr) = stop_tre(tre);
    assert!(exit_ok, "{stderr}");
    assert!(stdout.contains("skipped (bad input) 4"), "{stdout}");
    assert_no_errors_at_stop(&stderr);
    for why in [
        "no camera_info received yet",
        "camera_info is 320×480 but the image is 640×480",
        "encoding \"8UC2\" is not read",
        "no valid pixel",
        "frames are good again",
    ] {
        assert_eq!(stderr.matches(why).count(), 1, "{why:?} once in: {stderr}");
    }
}
