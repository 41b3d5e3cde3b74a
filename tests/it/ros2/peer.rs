//! The test's own ROS 2 node: it publishes the depth frames, camera_info and odometry that
//! `tre ros2` reads, and subscribes to what it publishes; discovery failures say what the
//! machine lacks.

use std::path::Path;
use std::process::Command;
use std::time::{Duration, Instant};

use ros2_client::qos::{Durability, History, Reliability, WhenFull};
use ros2_client::{
    Context, ContextOptions, MessageTypeName, Name, Node, NodeName, NodeOptions, Publisher,
    QosProfile, Subscription,
};
use tre::record::msgs::{
    CameraInfo, GridMap, Header, Image, OccupancyGrid, Odometry, Pose, RosMessage, Time,
};

use super::kitchen::{depth_msg, info_msg, odom_msg, stamp};

/// A domain id of this test process and test (RustDDS's ports follow the id; 0 to 232).
pub(super) fn domain_id(test: u16) -> u16 {
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
pub(super) struct Peer {
    _ctx: Context,
    node: Node,
    pub(super) depth: Publisher<Image>,
    pub(super) info: Publisher<CameraInfo>,
    odom: Publisher<Odometry>,
    pub(super) roughness: Subscription<Image>,
    pub(super) traversal: Subscription<Image>,
    pub(super) grid: Subscription<GridMap>,
    pub(super) occupancy: Subscription<OccupancyGrid>,
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
    pub(super) fn new(domain: u16) -> Self {
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
    pub(super) fn wait_for_tre(&self, odom: bool) {
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

    /// Publishes frame `i` (with its camera_info and pose) until the node answers with its
    /// roughness (a frame the node already has is dropped as stale, so a repeat is harmless).
    pub(super) fn send(&self, i: usize, depth_path: &Path, pose: Option<Pose>) -> Image {
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
pub(super) fn take_stamped<M: RosMessage + 'static>(
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
