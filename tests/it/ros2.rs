//! `tre ros2` against a second ROS 2 node (ros2-client, no ROS installation): the kitchen
//! sequence's real depth frames, camera_info and poses in; roughness images and a grid map out,
//! equal to `tre infer` and `tre map` on the same frames; bad input skipped while the node keeps
//! running; the recording read back by the Python `mcap` reader.
//!
//! RustDDS finds its peers by multicast on a multicast-capable interface (not loopback): each
//! test has a domain id of its own, and when no peer is found the test fails saying what the
//! machine lacks.
#![allow(clippy::unwrap_used)] // Test helpers fail loudly by design.

use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

use nalgebra::{Matrix3, Rotation3, UnitQuaternion};
use ros2_client::qos::{Durability, History, Reliability, WhenFull};
use ros2_client::{
    Context, ContextOptions, MessageTypeName, Name, Node, NodeName, NodeOptions, Publisher,
    QosProfile, Subscription,
};
use tre::record::msgs::{
    CameraInfo, GridMap, Header, Image, OccupancyGrid, Odometry, Point, Pose, PoseWithCovariance,
    Quaternion, RosMessage, Time,
};

use crate::common::{check_mcap, shared_data};

/// A domain id of this test process and test (RustDDS's ports follow the id; 0 to 232).
fn domain_id(test: u16) -> u16 {
    100 + ((std::process::id() % 40) as u16) * 3 + test
}

fn qos() -> QosProfile {
    QosProfile::publisher_default()
        .reliability(Reliability::Reliable {
            when_full: WhenFull::DEFAULT,
        })
        .history(History::KeepLast { depth: 4 })
}

fn latched() -> QosProfile {
    qos().durability(Durability::TransientLocal)
}

/// The test's own node: publishes the inputs, subscribes to the outputs.
struct Peer {
    _ctx: Context,
    node: Node,
    depth: Publisher<Image>,
    info: Publisher<CameraInfo>,
    odom: Publisher<Odometry>,
    roughness: Subscription<Image>,
    traversal: Subscription<Image>,
    grid: Subscription<GridMap>,
    occupancy: Subscription<OccupancyGrid>,
}

fn topic<M: RosMessage>(
    node: &mut Node,
    name: &str,
    q: &QosProfile,
) -> ros2_client::dds::rustdds::Topic {
    node.create_topic(
        &Name::parse(name).unwrap(),
        MessageTypeName::new(M::PACKAGE, M::NAME),
        q,
    )
    .unwrap()
}

impl Peer {
    fn new(domain: u16) -> Self {
        let ctx = Context::with_options(ContextOptions::new().domain_id(domain)).unwrap();
        let mut node = ctx
            .new_node(
                NodeName::new("/", &format!("tre_test_{}", std::process::id())).unwrap(),
                NodeOptions::new().enable_rosout(false),
            )
            .unwrap();
        let q = qos();
        let t = topic::<Image>(&mut node, "/camera/depth/image_rect_raw", &q);
        let depth = node.create_publisher(&t, Some(q.clone())).unwrap();
        let t = topic::<CameraInfo>(&mut node, "/camera/depth/camera_info", &q);
        let info = node.create_publisher(&t, Some(q.clone())).unwrap();
        let t = topic::<Odometry>(&mut node, "/odom", &q);
        let odom = node.create_publisher(&t, Some(q.clone())).unwrap();
        let t = topic::<Image>(&mut node, "/tre/roughness", &q);
        let roughness = node.create_subscription(&t, Some(q.clone())).unwrap();
        let t = topic::<Image>(&mut node, "/tre/traversal", &q);
        let traversal = node.create_subscription(&t, Some(q.clone())).unwrap();
        let t = topic::<GridMap>(&mut node, "/tre/grid_map", &q);
        let grid = node.create_subscription(&t, Some(q.clone())).unwrap();
        let l = latched();
        let t = topic::<OccupancyGrid>(&mut node, "/tre/occupancy", &l);
        let occupancy = node.create_subscription(&t, Some(l)).unwrap();
        let spinner = node.spinner().unwrap();
        std::thread::Builder::new()
            .name("test-ros2-spin".into())
            .spawn(move || futures::executor::block_on(spinner.spin()))
            .unwrap();
        Self {
            _ctx: ctx,
            node,
            depth,
            info,
            odom,
            roughness,
            traversal,
            grid,
            occupancy,
        }
    }

    /// Waits until the node under test has matched our depth publisher and roughness
    /// subscription; fails saying what discovery needs.
    fn wait_for_tre(&self, odom: bool) {
        let deadline = Instant::now() + Duration::from_secs(30);
        while self.depth.get_subscription_count(&self.node) == 0
            || self.info.get_subscription_count(&self.node) == 0
            || (odom && self.odom.get_subscription_count(&self.node) == 0)
            || self.roughness.get_publisher_count(&self.node) == 0
        {
            assert!(
                Instant::now() < deadline,
                "no ROS 2 peer discovered in 30 s: RustDDS discovers peers by UDP multicast \
                 (239.255.0.1) on a multicast-capable, up interface other than loopback; this \
                 machine's interfaces: {}",
                interfaces()
            );
            std::thread::sleep(Duration::from_millis(50));
        }
    }
}

/// `ip -brief link`, for the message of a failed discovery.
fn interfaces() -> String {
    Command::new("ip")
        .args(["-brief", "link"])
        .output()
        .map_or_else(
            |e| e.to_string(),
            |o| String::from_utf8_lossy(&o.stdout).replace('\n', "; "),
        )
}

/// Takes messages from `sub` until one stamped `stamp` arrives (older ones are dropped), or
/// `None` after `wait`.
fn take_stamped<M: RosMessage + 'static>(
    sub: &Subscription<M>,
    stamp: Time,
    wait: Duration,
    header: impl Fn(&M) -> &Header,
) -> Option<M> {
    let deadline = Instant::now() + wait;
    while Instant::now() < deadline {
        match sub.take() {
            Ok(Some((m, _))) if header(&m).stamp == stamp => return Some(m),
            Ok(Some(_)) => {}
            _ => std::thread::sleep(Duration::from_millis(5)),
        }
    }
    None
}

struct Kitchen {
    dir: PathBuf,
    stems: Vec<String>,
    camera: PathBuf,
    gravity: [f64; 3],
}

fn kitchen(n: usize) -> Option<Kitchen> {
    let dir = shared_data("data/real-rgbd-2/sevenscenes_redkitchen")?;
    let g: serde_json::Value =
        serde_json::from_slice(&std::fs::read(dir.join("gravity.json")).unwrap()).unwrap();
    let gravity = [0, 1, 2].map(|i| g["gravity"][i].as_f64().unwrap());
    Some(Kitchen {
        stems: (0..n).map(|i| format!("frame-{:06}", 5 * i)).collect(),
        dir,
        camera: Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("cameras/real-rgbd-2_sevenscenes_redkitchen.json"),
        gravity,
    })
}

fn stamp(i: usize) -> Time {
    Time {
        sec: 1_700_000_000 + i as i32,
        nanosec: 0,
    }
}

fn header(i: usize) -> Header {
    Header {
        stamp: stamp(i),
        frame_id: "camera_depth_optical_frame".into(),
    }
}

fn depth_msg(path: &Path, i: usize) -> Image {
    let img = image::open(path).unwrap().to_luma16();
    let (w, h) = img.dimensions();
    Image {
        header: header(i),
        height: h,
        width: w,
        encoding: "16UC1".into(),
        is_bigendian: 0,
        step: 2 * w,
        data: img.as_raw().iter().flat_map(|v| v.to_le_bytes()).collect(),
    }
}

fn info_msg(i: usize, (w, h): (u32, u32)) -> CameraInfo {
    CameraInfo {
        header: header(i),
        width: w,
        height: h,
        distortion_model: "plumb_bob".into(),
        d: vec![0.0; 5],
        k: [585.0, 0.0, 320.0, 0.0, 585.0, 240.0, 0.0, 0.0, 1.0],
        r: [1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0],
        p: [
            585.0, 0.0, 320.0, 0.0, 0.0, 585.0, 240.0, 0.0, 0.0, 0.0, 1.0, 0.0,
        ],
        ..CameraInfo::default()
    }
}

/// The kitchen pose of `stem` as a ROS pose, and the same pose after the node's quaternion
/// conversion as a 4×4 text `tre map` reads (so both fuse with the same bits).
fn pose_msg(k: &Kitchen, stem: &str) -> (Pose, String) {
    let text = std::fs::read_to_string(k.dir.join(format!("poses/{stem}.txt"))).unwrap();
    let v: Vec<f64> = text
        .split_whitespace()
        .map(|s| s.parse().unwrap())
        .collect();
    let m = Matrix3::new(v[0], v[1], v[2], v[4], v[5], v[6], v[8], v[9], v[10]);
    let q = UnitQuaternion::from_rotation_matrix(&Rotation3::from_matrix(&m));
    let pose = Pose {
        position: Point {
            x: v[3],
            y: v[7],
            z: v[11],
        },
        orientation: Quaternion {
            x: q.i,
            y: q.j,
            z: q.k,
            w: q.w,
        },
    };
    let p = tre::ros2::convert::map_pose(&pose, &tre::map::Pose::identity()).unwrap();
    let (r, t) = (p.rotation, p.translation);
    let text = format!(
        "{:?} {:?} {:?} {:?}\n{:?} {:?} {:?} {:?}\n{:?} {:?} {:?} {:?}\n0 0 0 1\n",
        r[(0, 0)],
        r[(0, 1)],
        r[(0, 2)],
        t.x,
        r[(1, 0)],
        r[(1, 1)],
        r[(1, 2)],
        t.y,
        r[(2, 0)],
        r[(2, 1)],
        r[(2, 2)],
        t.z,
    );
    (pose, text)
}

fn odom_msg(pose: Pose, i: usize) -> Odometry {
    Odometry {
        header: Header {
            stamp: stamp(i),
            frame_id: "world".into(),
        },
        child_frame_id: "camera_depth_optical_frame".into(),
        pose: PoseWithCovariance {
            pose,
            ..PoseWithCovariance::default()
        },
        ..Odometry::default()
    }
}

/// `tre ros2` as a child process, killed on drop: its stdout past the first line, and its
/// stderr as it comes (read on a thread of its own, so a test can wait for a log line).
struct Tre {
    child: Option<Child>,
    stdout: Option<std::io::BufReader<std::process::ChildStdout>>,
    first: String,
    log: std::sync::Arc<std::sync::Mutex<String>>,
    log_thread: Option<std::thread::JoinHandle<()>>,
}

impl Drop for Tre {
    fn drop(&mut self) {
        if let Some(c) = &mut self.child {
            let _ = c.kill();
            let _ = c.wait();
        }
    }
}

impl Tre {
    /// Waits until `needle` is in the log; false after `wait`.
    fn wait_for_log(&self, needle: &str, wait: Duration) -> bool {
        let deadline = Instant::now() + wait;
        while Instant::now() < deadline {
            if self.log.lock().unwrap().contains(needle) {
                return true;
            }
            std::thread::sleep(Duration::from_millis(20));
        }
        false
    }
}

fn start_tre(args: &[&str]) -> Tre {
    let mut child = Command::new(env!("CARGO_BIN_EXE_tre"))
        .current_dir(env!("CARGO_MANIFEST_DIR"))
        .arg("ros2")
        .args(args)
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let log = std::sync::Arc::new(std::sync::Mutex::new(String::new()));
    let stderr = child.stderr.take().unwrap();
    let sink = std::sync::Arc::clone(&log);
    let log_thread = std::thread::Builder::new()
        .name("tre-ros2-stderr".into())
        .spawn(move || {
            for line in std::io::BufRead::lines(std::io::BufReader::new(stderr)) {
                let Ok(line) = line else { break };
                let mut l = sink.lock().unwrap();
                l.push_str(&line);
                l.push('\n');
            }
        })
        .unwrap();
    // The node prints one line once it has joined the domain.
    let mut first = String::new();
    let mut out = std::io::BufReader::new(child.stdout.take().unwrap());
    std::io::BufRead::read_line(&mut out, &mut first).unwrap();
    if first.is_empty() {
        let _ = child.wait();
        let _ = log_thread.join();
        panic!("tre ros2 did not start: {}", log.lock().unwrap());
    }
    assert!(first.starts_with("ros2 node"), "{first}");
    Tre {
        child: Some(child),
        stdout: Some(out),
        first,
        log,
        log_thread: Some(log_thread),
    }
}

/// `tre ros2` stopped by SIGTERM: its exit status, stdout and stderr.
fn stop_tre(mut tre: Tre) -> (bool, String, String) {
    let mut child = tre.child.take().unwrap();
    Command::new("kill")
        .args(["-TERM", &child.id().to_string()])
        .status()
        .unwrap();
    let mut stdout = tre.first.clone();
    std::io::Read::read_to_string(&mut tre.stdout.take().unwrap(), &mut stdout).unwrap();
    let status = child.wait().unwrap();
    if let Some(t) = tre.log_thread.take() {
        t.join().unwrap();
    }
    let stderr = tre.log.lock().unwrap().clone();
    (status.success(), stdout, stderr)
}

/// A clean stop logs nothing at error level: the node takes its publishers, subscriptions,
/// node, spinner and participant down in the order the DDS libraries need (else they print
/// "Cannot remove Reader/Writer" and "Cannot notify spin task" errors).
fn assert_no_errors_at_stop(stderr: &str) {
    let errors: Vec<&str> = stderr
        .lines()
        .filter(|l| {
            l.contains("ERROR") || l.contains("Cannot remove") || l.contains("Cannot notify")
        })
        .collect();
    assert!(
        errors.is_empty(),
        "errors logged: {errors:#?}\nin: {stderr}"
    );
}

fn f32_values(img: &Image) -> Vec<f32> {
    assert_eq!(img.encoding, "32FC1");
    img.data
        .chunks_exact(4)
        .map(|b| f32::from_le_bytes([b[0], b[1], b[2], b[3]]))
        .collect()
}

fn npy_f32(path: &Path) -> Vec<f32> {
    let a = tre::io::npy::read_npy(std::fs::File::open(path).unwrap()).unwrap();
    let g = tre::io::npy_grid(a).unwrap();
    g.as_slice().iter().map(|&v| v as f32).collect()
}

fn same_bits(a: &[f32], b: &[f32]) -> bool {
    a.len() == b.len()
        && a.iter()
            .zip(b)
            .all(|(x, y)| x.to_bits() == y.to_bits() || (x.is_nan() && y.is_nan()))
}

/// One layer of a GridMap message in `tre map`'s layout (row-major, column 0 at the smallest
/// x, row 0 at the largest y).
fn grid_layer(g: &GridMap, name: &str) -> Vec<f32> {
    let i = g.layers.iter().position(|l| l == name).unwrap();
    let a = &g.data[i];
    assert_eq!(a.layout.dim[0].label, "column_index");
    assert_eq!(a.layout.dim[1].label, "row_index");
    let side = a.layout.dim[1].size as usize;
    let mut out = Vec::with_capacity(side * side);
    for c in 0..side {
        out.extend(a.data[c * side..(c + 1) * side].iter().rev());
    }
    out
}

impl Peer {
    /// Publishes frame `i` (with its camera_info and pose) until the node answers with its
    /// roughness (a frame the node already has is dropped as stale, so a repeat is harmless).
    fn send(&self, i: usize, depth_path: &Path, pose: Option<Pose>) -> Image {
        let depth = depth_msg(depth_path, i);
        let info = info_msg(i, (depth.width, depth.height));
        for _ in 0..5 {
            if let Some(pose) = pose {
                self.odom.publish(odom_msg(pose, i)).unwrap();
            }
            self.info.publish(info.clone()).unwrap();
            self.depth.publish(depth.clone()).unwrap();
            let out = take_stamped(&self.roughness, stamp(i), Duration::from_secs(8), |m| {
                &m.header
            });
            if let Some(out) = out {
                return out;
            }
        }
        panic!("no roughness for frame {i}")
    }
}

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
        same_bits(&f32_values(&roughness), &npy_f32(&npy)),
        "{stem}: the node's roughness differs from tre infer's"
    );
    grid
}

/// The folders of a `tre map` sequence, its gravity and camera (the frames and poses follow).
fn map_sequence(k: &Kitchen, seq: &Path) {
    for sub in ["depth", "poses"] {
        std::fs::create_dir_all(seq.join(sub)).unwrap();
    }
    std::fs::copy(k.dir.join("gravity.json"), seq.join("gravity.json")).unwrap();
    std::fs::copy(&k.camera, seq.join("intrinsics.json")).unwrap();
}

fn run_tre_map(seq: &Path, out: &Path) {
    let o = Command::new(env!("CARGO_BIN_EXE_tre"))
        .arg("map")
        .arg(seq)
        .arg("-o")
        .arg(out)
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
}

/// `tre infer --mode geometric` on a depth PNG, written as `.npy`.
fn infer_npy(depth: &Path, camera: &Path, npy: &Path) {
    let o = Command::new(env!("CARGO_BIN_EXE_tre"))
        .current_dir(env!("CARGO_MANIFEST_DIR"))
        .args(["infer", "--mode", "geometric", "--format", "npy", "--depth"])
        .arg(depth)
        .arg("--camera")
        .arg(camera)
        .arg("-o")
        .arg(npy)
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
}

/// The occupancy grid is the map's three-state layer: rows from the bottom, unknown -1,
/// traversable 0, hazard 100.
fn assert_occupancy_is_traversal(occupancy: &OccupancyGrid, traversal: &[f32]) {
    let side = occupancy.info.width as usize;
    assert_eq!(traversal.len(), side * side);
    for iy in 0..side {
        for x in 0..side {
            let want = match traversal[(side - 1 - iy) * side + x] as u8 {
                1 => 0,
                2 => 100,
                _ => -1,
            };
            assert_eq!(occupancy.data[iy * side + x], want);
        }
    }
    assert!(occupancy.data.contains(&0) && occupancy.data.contains(&-1));
}

/// Quiet logs at the default level while running: nothing from the DDS libraries, at most a
/// line a frame.
fn assert_quiet_while_running(tre: &Tre, frames: usize) {
    let running = tre.log.lock().unwrap().clone();
    assert!(
        !running.contains("rustdds") && !running.contains("ros2_client"),
        "{running}"
    );
    assert!(
        running.lines().count() <= frames,
        "{} log lines for {} frames: {running}",
        running.lines().count(),
        frames
    );
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
                &npy_f32(&out.join(format!("{name}.npy")))
            ),
            "layer {name}: the node's map differs from tre map's"
        );
    }
    assert_occupancy_is_traversal(&occupancy, &npy_f32(&out.join("traversal.npy")));
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
