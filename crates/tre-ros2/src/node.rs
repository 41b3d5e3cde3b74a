//! The ROS 2 node: subscriptions, the latest-frame slot, the worker that runs the pipeline and
//! the map, and the publishers (docs/ros2.md).
//!
//! Two threads. The DDS thread runs ros2-client's spinner and the subscriptions: a depth (or
//! colour) frame goes into a one-frame slot, replacing a frame still waiting there (counted as
//! dropped), so a slow pipeline never queues stale frames; camera_info and poses are kept
//! (the latest camera_info, the last 256 poses). The worker thread takes the slot, finds the
//! pose nearest the frame's stamp, runs the [`Processor`], and publishes every output with
//! the input's header (the map with the map frame's id), then records it when asked.

use std::collections::VecDeque;
use std::path::PathBuf;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Condvar, Mutex, MutexGuard};
use std::thread::JoinHandle;
use std::time::Duration;

use futures::future::FusedFuture;
use futures::{FutureExt, StreamExt};
use ros2_client::qos::{Durability, History, Reliability as DdsReliability, WhenFull};
use ros2_client::{
    Context, ContextOptions, MessageTypeName, Name, Node, NodeName, NodeOptions, QosProfile,
    Subscription,
};
use tre_core::map::Pose as MapPose;
use tre_pipeline::Mode;
use tre_record::msgs::{CameraInfo, Image, Odometry, PoseStamped, RosMessage, Time};
use tre_record::{now_ns, RecordOptions, Recorder};

use crate::convert;
use crate::error::{DdsFault, Ros2Error};
use crate::process::{FrameMsgs, Processor};

mod config;
mod worker;

pub use config::{NodeConfig, NodeStats, PoseSource, Reliability};
use worker::{work, Publishers};

/// A running node; [`RunningNode::stop`] stops it and finishes the recording.
#[derive(Debug)]
pub struct RunningNode {
    shared: Arc<Shared>,
    stop_dds: Option<futures::channel::oneshot::Sender<()>>,
    /// The DDS thread; it joins the worker when it stops, and returns the worker's result.
    dds: Option<JoinHandle<WorkerResult>>,
}

#[derive(Debug, Default)]
struct Inbox {
    frame: Option<FrameMsgs>,
    /// Unmatched depth and colour frames of the rgbd mode (a few of each).
    depth: VecDeque<Image>,
    colour: VecDeque<Image>,
    info: Option<CameraInfo>,
    poses: VecDeque<(i64, MapPose)>,
    /// Inputs to record, in arrival order: (topic, message bytes as CDR of its type).
    record: Vec<Recorded>,
    stop: bool,
}

#[derive(Debug)]
enum Recorded {
    Image(String, Box<Image>, u64),
    Info(String, Box<CameraInfo>, u64),
    Odometry(String, Box<Odometry>, u64),
    PoseStamped(String, Box<PoseStamped>, u64),
}

#[derive(Debug, Default)]
struct Shared {
    inbox: Mutex<Inbox>,
    ready: Condvar,
    stats: NodeStats,
    recording: AtomicBool,
}

impl Shared {
    fn lock(&self) -> MutexGuard<'_, Inbox> {
        self.inbox.lock().unwrap_or_else(|e| e.into_inner())
    }
}

fn dds<E: std::fmt::Debug + Send + Sync + 'static>(what: &'static str) -> impl Fn(E) -> Ros2Error {
    move |e| Ros2Error::Dds {
        what,
        fault: DdsFault::Refused(Box::new(e)),
    }
}

fn name(full: &str) -> Result<Name, Ros2Error> {
    Name::parse(full).map_err(|e| Ros2Error::Name {
        name: full.to_owned(),
        why: Box::new(e),
    })
}

fn qos(r: Reliability) -> QosProfile {
    let q = QosProfile::subscription_default().history(History::KeepLast { depth: 2 });
    match r {
        Reliability::BestEffort => q,
        Reliability::Reliable => q.reliability(DdsReliability::Reliable {
            when_full: WhenFull::DEFAULT,
        }),
    }
}

/// Outputs: reliable, keep the last one; the occupancy grid also transient-local, as Nav2's
/// static layer subscribes.
fn output_qos(latched: bool) -> QosProfile {
    let q = QosProfile::publisher_default()
        .reliability(DdsReliability::Reliable {
            when_full: WhenFull::Wait(Duration::from_millis(20)),
        })
        .history(History::KeepLast { depth: 1 });
    if latched {
        q.durability(Durability::TransientLocal)
    } else {
        q
    }
}

/// The node's subscriptions: the mode's images, their camera_info, the pose source.
struct Subscriptions {
    depth: Option<Subscription<Image>>,
    colour: Option<Subscription<Image>>,
    info: Subscription<CameraInfo>,
    odom: Option<Subscription<Odometry>>,
    pose: Option<Subscription<PoseStamped>>,
}

fn subscribe<M: RosMessage + 'static>(
    node: &mut Node,
    topic: &str,
    q: &QosProfile,
) -> Result<Subscription<M>, Ros2Error> {
    let t = node
        .create_topic(&name(topic)?, MessageTypeName::new(M::PACKAGE, M::NAME), q)
        .map_err(dds("topic"))?;
    node.create_subscription::<M>(&t, Some(q.clone()))
        .map_err(dds("subscription"))
}

impl Subscriptions {
    fn new(node: &mut Node, c: &NodeConfig, mode: Mode) -> Result<Self, Ros2Error> {
        let q = qos(c.input_reliability);
        let (depth, colour) = match mode {
            Mode::Geometric => (Some(subscribe(node, &c.depth_topic, &q)?), None),
            Mode::Rgb => (None, Some(subscribe(node, &c.colour_topic, &q)?)),
            Mode::Rgbd => (
                Some(subscribe(node, &c.depth_topic, &q)?),
                Some(subscribe(node, &c.colour_topic, &q)?),
            ),
        };
        let (odom, pose) = match &c.pose {
            Some(PoseSource::Odometry(t)) => (Some(subscribe(node, t, &q)?), None),
            Some(PoseSource::PoseStamped(t)) => (None, Some(subscribe(node, t, &q)?)),
            None => (None, None),
        };
        Ok(Self {
            depth,
            colour,
            info: subscribe(node, &c.info_topic, &q)?,
            odom,
            pose,
        })
    }

    /// Receives until every stream ends (they do not: the caller stops it).
    async fn receive(&self, sh: &Shared, c: &NodeConfig, mode: Mode) {
        let info = self.info.async_stream().for_each(|m| async {
            if let Ok((info, _)) = m {
                let mut inbox = sh.lock();
                if sh.recording.load(Ordering::Relaxed) {
                    let r = Recorded::Info(c.info_topic.clone(), Box::new(info.clone()), now_ns());
                    inbox.record.push(r);
                }
                inbox.info = Some(info);
            }
        });
        let odom = async {
            if let Some(s) = &self.odom {
                s.async_stream()
                    .for_each(|m| async {
                        if let Ok((o, _)) = m {
                            on_pose(sh, c, &o.header.stamp, &o.pose.pose);
                            if sh.recording.load(Ordering::Relaxed) {
                                let r = Recorded::Odometry(pose_topic(c), Box::new(o), now_ns());
                                sh.lock().record.push(r);
                            }
                        }
                    })
                    .await;
            }
        };
        let pose = async {
            if let Some(s) = &self.pose {
                s.async_stream()
                    .for_each(|m| async {
                        if let Ok((p, _)) = m {
                            on_pose(sh, c, &p.header.stamp, &p.pose);
                            if sh.recording.load(Ordering::Relaxed) {
                                let r = Recorded::PoseStamped(pose_topic(c), Box::new(p), now_ns());
                                sh.lock().record.push(r);
                            }
                        }
                    })
                    .await;
            }
        };
        futures::join!(
            receive_images(self.depth.as_ref(), sh, c, mode, true),
            receive_images(self.colour.as_ref(), sh, c, mode, false),
            info,
            odom,
            pose
        );
    }
}

async fn receive_images(
    sub: Option<&Subscription<Image>>,
    sh: &Shared,
    c: &NodeConfig,
    mode: Mode,
    is_depth: bool,
) {
    if let Some(s) = sub {
        s.async_stream()
            .for_each(|m| async {
                if let Ok((img, _)) = m {
                    on_image(sh, c, mode, img, is_depth);
                }
            })
            .await;
    }
}

fn thread_error(e: std::io::Error) -> Ros2Error {
    Ros2Error::Dds {
        what: "thread",
        fault: e.into(),
    }
}

/// The recording `config` asks for, if any.
fn recorder(config: &NodeConfig) -> Result<Option<Recorder>, Ros2Error> {
    let options = RecordOptions {
        foxglove: config.record_foxglove,
    };
    let path = config.record.as_deref();
    Ok(path
        .map(|p| Recorder::create_with(p, options))
        .transpose()?)
}

/// Starts the node: joins the domain, subscribes and publishes, and returns at once; frames
/// are processed on a thread of its own until [`RunningNode::stop`].
pub fn start(config: NodeConfig, processor: Processor) -> Result<RunningNode, Ros2Error> {
    let context = Context::with_options(ContextOptions::new().domain_id(config.domain_id))
        .map_err(dds("DDS participant"))?;
    let (ns, base) = match config.node_name.rsplit_once('/') {
        Some((ns, base)) => (if ns.is_empty() { "/" } else { ns }, base),
        None => ("/", config.node_name.as_str()),
    };
    let node_name = NodeName::new(ns, base).map_err(|e| Ros2Error::Name {
        name: config.node_name.clone(),
        why: Box::new(e),
    })?;
    let mut node = context
        .new_node(node_name, NodeOptions::new().enable_rosout(false))
        .map_err(dds("node"))?;
    let mode = processor.config().mode;
    let subs = Subscriptions::new(&mut node, &config, mode)?;
    let publishers = Publishers::new(&mut node, &config)?;
    let recorder = recorder(&config)?;
    let shared = Arc::new(Shared::default());
    shared
        .recording
        .store(recorder.is_some(), Ordering::Relaxed);
    let (stop_tx, stop_rx) = futures::channel::oneshot::channel::<()>();
    let spinner = node.spinner().map_err(dds("spinner"))?;
    let worker_shared = Arc::clone(&shared);
    let topics = config.clone();
    let worker = std::thread::Builder::new()
        .name("tre-ros2-worker".into())
        .spawn(move || work(&worker_shared, &config, processor, publishers, recorder))
        .map_err(thread_error)?;
    let dds_shared = Arc::clone(&shared);
    let dds = std::thread::Builder::new()
        .name("tre-ros2-dds".into())
        .spawn(move || {
            let dds = Dds {
                context,
                node,
                subs,
                spinner,
            };
            dds.run(&dds_shared, &topics, mode, stop_rx, worker)
        })
        .map_err(thread_error)?;
    Ok(RunningNode {
        shared,
        stop_dds: Some(stop_tx),
        dds: Some(dds),
    })
}

/// What the DDS thread owns, stopped in the order the libraries need (so a clean stop logs
/// nothing): the worker and its publishers first, then the subscriptions, then the node (which
/// tells the spinner to stop), the spinner run until it has stopped, the participant last.
struct Dds {
    context: Context,
    node: Node,
    subs: Subscriptions,
    spinner: ros2_client::Spinner,
}

/// The worker thread's result: the recording's path.
type WorkerResult = Result<Option<PathBuf>, Ros2Error>;

impl Dds {
    /// Receives until `stop` fires, then waits for the worker and takes everything down.
    fn run(
        self,
        sh: &Shared,
        c: &NodeConfig,
        mode: Mode,
        stop: futures::channel::oneshot::Receiver<()>,
        worker: JoinHandle<WorkerResult>,
    ) -> WorkerResult {
        let Self {
            context,
            node,
            subs,
            spinner,
        } = self;
        let mut spin = Box::pin(
            spinner
                .spin()
                .map(|r| {
                    if let Err(e) = r {
                        tracing::error!("ROS 2 spinner stopped: {e:?}");
                    }
                })
                .fuse(),
        );
        futures::executor::block_on(async {
            futures::select! {
                () = subs.receive(sh, c, mode).fuse() => {},
                () = spin => {},
                _ = stop.fuse() => {},
            }
        });
        // The worker may still be publishing its last frame: it stops first, its publishers
        // with it.
        let worked = worker.join().map_err(|_| Ros2Error::Dds {
            what: "worker thread",
            fault: DdsFault::Panicked,
        });
        drop(subs);
        drop(node);
        if !spin.is_terminated() {
            futures::executor::block_on(&mut spin);
        }
        drop(spin);
        drop(context);
        worked?
    }
}

fn pose_topic(c: &NodeConfig) -> String {
    match &c.pose {
        Some(PoseSource::Odometry(t) | PoseSource::PoseStamped(t)) => t.clone(),
        None => String::new(),
    }
}

fn on_pose(sh: &Shared, c: &NodeConfig, stamp: &Time, pose: &tre_record::msgs::Pose) {
    match convert::map_pose(pose, &c.camera_in_body) {
        Ok(p) => {
            let mut inbox = sh.lock();
            inbox.poses.push_back((stamp.nanos(), p));
            while inbox.poses.len() > 256 {
                inbox.poses.pop_front();
            }
            drop(inbox);
            sh.ready.notify_all();
        }
        Err(e) => tracing::warn!("pose skipped: {e}"),
    }
}

/// rgbd: the depth and colour frames of one stamp make a frame; an unmatched one waits (the
/// last four of each).
fn pair_rgbd(inbox: &mut Inbox, img: Image, is_depth: bool) -> Option<FrameMsgs> {
    let stamp = img.header.stamp;
    let (mine, other) = if is_depth {
        (&mut inbox.depth, &mut inbox.colour)
    } else {
        (&mut inbox.colour, &mut inbox.depth)
    };
    let Some(i) = other.iter().position(|o| o.header.stamp == stamp) else {
        mine.push_back(img);
        while mine.len() > 4 {
            mine.pop_front();
        }
        return None;
    };
    let partner = other.remove(i).expect("index found above");
    other.retain(|o| o.header.stamp > stamp);
    mine.retain(|o| o.header.stamp > stamp);
    let (depth, colour) = if is_depth {
        (img, partner)
    } else {
        (partner, img)
    };
    Some(FrameMsgs {
        depth: Some(depth),
        colour: Some(colour),
        info: None,
        pose: None,
    })
}

/// A depth or colour frame arrives: it becomes the waiting frame (with its partner in rgbd).
fn on_image(sh: &Shared, c: &NodeConfig, mode: Mode, img: Image, is_depth: bool) {
    let mut inbox = sh.lock();
    if sh.recording.load(Ordering::Relaxed) {
        let topic = if is_depth {
            &c.depth_topic
        } else {
            &c.colour_topic
        };
        inbox.record.push(Recorded::Image(
            topic.clone(),
            Box::new(img.clone()),
            now_ns(),
        ));
    }
    let frame = match mode {
        Mode::Geometric => Some(FrameMsgs {
            depth: Some(img),
            colour: None,
            info: None,
            pose: None,
        }),
        Mode::Rgb => Some(FrameMsgs {
            depth: None,
            colour: Some(img),
            info: None,
            pose: None,
        }),
        Mode::Rgbd => pair_rgbd(&mut inbox, img, is_depth),
    };
    if let Some(f) = frame {
        sh.stats.received.fetch_add(1, Ordering::Relaxed);
        if inbox.frame.replace(f).is_some() {
            sh.stats.dropped.fetch_add(1, Ordering::Relaxed);
        }
        drop(inbox);
        sh.ready.notify_all();
    }
}

impl RunningNode {
    /// What the node has done so far.
    pub fn stats(&self) -> &NodeStats {
        &self.shared.stats
    }

    /// Stops the node (the worker finishes the frame it is on) and finishes the recording;
    /// returns its path.
    pub fn stop(mut self) -> Result<Option<PathBuf>, Ros2Error> {
        self.shared.lock().stop = true;
        self.shared.ready.notify_all();
        if let Some(tx) = self.stop_dds.take() {
            let _ = tx.send(());
        }
        match self.dds.take() {
            Some(h) => h.join().map_err(|_| Ros2Error::Dds {
                what: "DDS thread",
                fault: DdsFault::Panicked,
            })?,
            None => Ok(None),
        }
    }
}

impl Drop for RunningNode {
    fn drop(&mut self) {
        self.shared.lock().stop = true;
        self.shared.ready.notify_all();
        if let Some(tx) = self.stop_dds.take() {
            let _ = tx.send(());
        }
    }
}
