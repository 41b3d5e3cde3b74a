//! The worker thread: takes the latest frame, finds its pose, runs the processor, publishes
//! and records the outputs.

use std::collections::VecDeque;
use std::sync::atomic::Ordering;
use std::time::Duration;

use ros2_client::{MessageTypeName, Node, Publisher};
use tre_core::map::Pose as MapPose;
use tre_record::msgs::{CompressedImage, GridMap, Image, OccupancyGrid, RosMessage, Time};
use tre_record::{now_ns, Recorder};

use super::{dds, name, output_qos, NodeConfig, NodeStats, Recorded, Shared, WorkerResult};
use crate::error::Ros2Error;
use crate::limiter::Limiter;
use crate::process::{Outputs, Processor};

pub(super) struct Publishers {
    prefix: String,
    roughness: Publisher<Image>,
    uncertainty: Publisher<Image>,
    traversal: Publisher<Image>,
    /// `{image}/compressed` of the roughness, the uncertainty and the three-state image, with
    /// that topic under the prefix.
    compressed: [(&'static str, Publisher<CompressedImage>); 3],
    grid: Publisher<GridMap>,
    occupancy: Publisher<OccupancyGrid>,
}

impl Publishers {
    pub(super) fn new(node: &mut Node, c: &NodeConfig) -> Result<Self, Ros2Error> {
        let prefix = c.output_prefix.trim_end_matches('/').to_owned();
        fn make<M: RosMessage + 'static>(
            node: &mut Node,
            topic: &str,
            latched: bool,
        ) -> Result<Publisher<M>, Ros2Error> {
            let q = output_qos(latched);
            let t = node
                .create_topic(&name(topic)?, MessageTypeName::new(M::PACKAGE, M::NAME), &q)
                .map_err(dds("topic"))?;
            node.create_publisher::<M>(&t, Some(q))
                .map_err(dds("publisher"))
        }
        let mut png = |topic: &'static str| {
            make(node, &format!("{prefix}/{topic}"), false).map(|p| (topic, p))
        };
        let compressed = [
            png("roughness/compressed")?,
            png("uncertainty/compressed")?,
            png("traversal/compressed")?,
        ];
        Ok(Self {
            roughness: make(node, &format!("{prefix}/roughness"), false)?,
            uncertainty: make(node, &format!("{prefix}/uncertainty"), false)?,
            traversal: make(node, &format!("{prefix}/traversal"), false)?,
            compressed,
            grid: make(node, &format!("{prefix}/grid_map"), false)?,
            occupancy: make(node, &format!("{prefix}/occupancy"), true)?,
            prefix,
        })
    }

    fn publish(&self, o: &Outputs, stats: &NodeStats) {
        send(stats, &self.roughness, "roughness", Some(&o.roughness));
        send(
            stats,
            &self.uncertainty,
            "uncertainty",
            o.uncertainty.as_ref(),
        );
        send(stats, &self.traversal, "traversal", o.traversal.as_ref());
        for (name, img) in &o.compressed {
            let of_image =
                |(topic, _): &&(&str, _)| topic.strip_suffix("/compressed") == Some(name);
            if let Some((topic, p)) = self.compressed.iter().find(of_image) {
                send(stats, p, topic, Some(img));
            }
        }
        send(stats, &self.grid, "grid_map", o.grid.as_ref());
        send(stats, &self.occupancy, "occupancy", o.occupancy.as_ref());
    }
}

/// Publishes `msg` when there is one and counts it as written or unsent; a refusal is logged
/// (the next frame publishes again).
fn send<M: RosMessage + Clone + std::fmt::Debug>(
    stats: &NodeStats,
    publisher: &Publisher<M>,
    topic: &'static str,
    msg: Option<&M>,
) {
    if let Some(m) = msg {
        match publisher.publish(m.clone()) {
            Ok(()) => {
                let mut w = stats.written.lock().unwrap_or_else(|e| e.into_inner());
                *w.entry(topic).or_default() += 1;
            }
            Err(e) => {
                stats.unsent.fetch_add(1, Ordering::Relaxed);
                tracing::warn!("publishing {topic}: {e:?}");
            }
        }
    }
}

/// The pose nearest `stamp` within `tolerance`.
fn nearest_pose(
    poses: &VecDeque<(i64, MapPose)>,
    stamp: i64,
    tolerance: Duration,
) -> Option<MapPose> {
    poses
        .iter()
        .min_by_key(|(t, _)| (t - stamp).unsigned_abs())
        .filter(|(t, _)| (t - stamp).unsigned_abs() <= tolerance.as_nanos() as u64)
        .map(|(_, p)| *p)
}

pub(super) fn work(
    sh: &Shared,
    c: &NodeConfig,
    mut processor: Processor,
    pubs: Publishers,
    mut recorder: Option<Recorder>,
) -> WorkerResult {
    let mut limiter = Limiter::new(c.log_every);
    let mut last_stamp: Option<Time> = None;
    loop {
        let (mut frame, recorded) = {
            let mut inbox = sh.lock();
            while inbox.frame.is_none() && !inbox.stop {
                inbox = sh.ready.wait(inbox).unwrap_or_else(|e| e.into_inner());
            }
            if inbox.stop {
                let recorded = std::mem::take(&mut inbox.record);
                drop(inbox);
                if let Some(r) = &mut recorder {
                    write_inputs(r, recorded)?;
                }
                break;
            }
            let mut frame = inbox.frame.take().expect("checked above");
            frame.info = inbox.info.clone();
            (frame, std::mem::take(&mut inbox.record))
        };
        if let Some(r) = &mut recorder {
            write_inputs(r, recorded)?;
        }
        let stamp = frame.header().stamp;
        if last_stamp.is_some_and(|l| stamp <= l) {
            sh.stats.dropped.fetch_add(1, Ordering::Relaxed);
            continue;
        }
        if c.pose.is_some() {
            frame.pose = wait_for_pose(sh, stamp.nanos(), c.pose_tolerance);
        }
        match processor.process(&frame) {
            Ok(out) => {
                last_stamp = Some(stamp);
                limiter.good();
                pubs.publish(&out, &sh.stats);
                sh.stats.published.fetch_add(1, Ordering::Relaxed);
                if out.layers.is_some() {
                    sh.stats.fused.fetch_add(1, Ordering::Relaxed);
                }
                if out.grid.is_some() {
                    sh.stats.grids.fetch_add(1, Ordering::Relaxed);
                }
                log_not_fused(&mut limiter, &out, c.pose.is_some() && frame.pose.is_none());
                if let Some(r) = &mut recorder {
                    write_outputs(r, &pubs, &out, &processor)?;
                }
            }
            Err(e) => {
                sh.stats.skipped.fetch_add(1, Ordering::Relaxed);
                limiter.skipped(e.kind(), &e.to_string());
            }
        }
    }
    drop(pubs);
    finish_recording(recorder, c)
}

/// Finishes the recording, if any, as a rosbag2 folder when asked; its path.
fn finish_recording(recorder: Option<Recorder>, c: &NodeConfig) -> WorkerResult {
    let finish = |r: Recorder| {
        if c.record_bag {
            r.finish_bag(ros2_client::COMPILED_ROS_DISTRO.as_str())
        } else {
            r.finish()
        }
    };
    Ok(recorder.map(finish).transpose()?)
}

/// Logs (limited) why a published frame was not fused into the map.
fn log_not_fused(limiter: &mut Limiter, out: &Outputs, pose_missing: bool) {
    if let Some(e) = &out.map_error {
        limiter.skipped("map", &format!("not fused into the map: {e}"));
    }
    if pose_missing {
        limiter.skipped(
            "pose missing",
            "no pose within the tolerance of the frame's stamp: not fused",
        );
    }
}

/// The pose for a frame: one already within the tolerance, else the first to arrive within
/// the tolerance of the frame's stamp (waiting at most the tolerance, plus 100 ms).
fn wait_for_pose(sh: &Shared, stamp: i64, tolerance: Duration) -> Option<MapPose> {
    let deadline = std::time::Instant::now() + tolerance + Duration::from_millis(100);
    let mut inbox = sh.lock();
    loop {
        if let Some(p) = nearest_pose(&inbox.poses, stamp, tolerance) {
            return Some(p);
        }
        let now = std::time::Instant::now();
        if now >= deadline || inbox.stop {
            return None;
        }
        inbox = sh
            .ready
            .wait_timeout(inbox, deadline - now)
            .unwrap_or_else(|e| e.into_inner())
            .0;
    }
}

fn write_inputs(r: &mut Recorder, recorded: Vec<Recorded>) -> Result<(), Ros2Error> {
    for m in recorded {
        match m {
            Recorded::Image(t, img, ns) => r.ros(&t, &*img, &img.header.stamp, ns)?,
            Recorded::Info(t, info, ns) => r.ros(&t, &*info, &info.header.stamp, ns)?,
            Recorded::Odometry(t, o, ns) => r.ros(&t, &*o, &o.header.stamp, ns)?,
            Recorded::PoseStamped(t, p, ns) => r.ros(&t, &*p, &p.header.stamp, ns)?,
        }
    }
    Ok(())
}

fn write_outputs(
    r: &mut Recorder,
    pubs: &Publishers,
    out: &Outputs,
    processor: &Processor,
) -> Result<(), Ros2Error> {
    let p = &pubs.prefix;
    let ns = now_ns();
    let stamp = out.roughness.header.stamp;
    r.ros(&format!("{p}/roughness"), &out.roughness, &stamp, ns)?;
    r.raw_image(&format!("{p}/roughness/foxglove"), &out.roughness, ns)?;
    if let Some(u) = &out.uncertainty {
        r.ros(&format!("{p}/uncertainty"), u, &stamp, ns)?;
    }
    if let Some(t) = &out.traversal {
        r.ros(&format!("{p}/traversal"), t, &stamp, ns)?;
    }
    for (name, img) in &out.compressed {
        r.ros(&format!("{p}/{name}/compressed"), img, &stamp, ns)?;
    }
    if let Some(g) = &out.grid {
        r.ros(&format!("{p}/grid_map"), g, &stamp, ns)?;
        if let (Some(map), Some(layers)) = (processor.map(), &out.layers) {
            r.grid(&format!("{p}/grid/foxglove"), &g.header, map, layers, ns)?;
        }
    }
    if let Some(o) = &out.occupancy {
        r.ros(&format!("{p}/occupancy"), o, &stamp, ns)?;
    }
    Ok(())
}
