//! Recordings as MCAP: every message in its ROS 2 type (`ros2msg` schema, CDR), which
//! `ros2 bag`, Foxglove and the `mcap` tools read, in zstd-compressed chunks, each channel
//! with the `offered_qos_profiles` rosbag2 replays it with (transient-local for the occupancy
//! grid) and its ROS 2 type hash (`topic_type_hash`, [`crate::type_hash`]). On request
//! ([`RecordOptions::foxglove`]) the outputs again in Foxglove's own schemas
//! (`foxglove.RawImage`, `foxglove.Grid`; JSON), which Foxglove shows with no extension but
//! which rosbag2 refuses beside CDR (docs/ros2.md says which viewer shows which channel).
//! [`Recorder::finish_bag`] also writes rosbag2's `metadata.yaml` beside the file.

use std::collections::BTreeMap;
use std::fs::File;
use std::io::BufWriter;
use std::path::{Path, PathBuf};

use base64::Engine as _;
use image::RgbImage;
use serde_json::json;
use tre_core::geometry::{Grid, Intrinsics};
use tre_core::map::{GridMap as Map, Layers, Pose as MapPose, LAYER_NAMES};
use tre_core::roughness::traversal::Traversal;

use crate::encode;
use crate::msgs::{to_cdr, Header, Image, RosMessage, Time};

/// JSON Schema of `foxglove.RawImage` (the fields this writer fills).
const RAW_IMAGE_SCHEMA: &str = r#"{"title":"foxglove.RawImage","type":"object","properties":{"timestamp":{"type":"object","properties":{"sec":{"type":"integer"},"nsec":{"type":"integer"}}},"frame_id":{"type":"string"},"width":{"type":"integer"},"height":{"type":"integer"},"encoding":{"type":"string"},"step":{"type":"integer"},"data":{"type":"string","contentEncoding":"base64"}}}"#;

/// JSON Schema of `foxglove.Grid` (the fields this writer fills).
const GRID_SCHEMA: &str = r#"{"title":"foxglove.Grid","type":"object","properties":{"timestamp":{"type":"object","properties":{"sec":{"type":"integer"},"nsec":{"type":"integer"}}},"frame_id":{"type":"string"},"pose":{"type":"object","properties":{"position":{"type":"object","properties":{"x":{"type":"number"},"y":{"type":"number"},"z":{"type":"number"}}},"orientation":{"type":"object","properties":{"x":{"type":"number"},"y":{"type":"number"},"z":{"type":"number"},"w":{"type":"number"}}}}},"column_count":{"type":"integer"},"cell_size":{"type":"object","properties":{"x":{"type":"number"},"y":{"type":"number"}}},"row_stride":{"type":"integer"},"cell_stride":{"type":"integer"},"fields":{"type":"array","items":{"type":"object","properties":{"name":{"type":"string"},"offset":{"type":"integer"},"type":{"type":"integer"}}}},"data":{"type":"string","contentEncoding":"base64"}}}"#;

/// `foxglove.NumericType` of a float32 field.
const FOXGLOVE_FLOAT32: u32 = 7;

/// What a recording holds beyond the ROS 2 channels.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct RecordOptions {
    /// Also the Foxglove JSON-schema channels (the roughness as `foxglove.RawImage`, the map
    /// as `foxglove.Grid`). Off by default: rosbag2 refuses a bag of mixed serialisations.
    pub foxglove: bool,
}

/// `offered_qos_profiles` of a channel as rosbag2 writes it (one profile; the integers of the
/// rmw enums: history 1 keep-last, reliability 1 reliable, durability 1 transient-local or
/// 2 volatile, liveliness 1 automatic; zero durations: the default).
fn offered_qos(transient_local: bool) -> String {
    let durability = if transient_local { 1 } else { 2 };
    let zero = "\n    sec: 0\n    nsec: 0";
    format!(
        "- history: 1\n  depth: 1\n  reliability: 1\n  durability: {durability}\n  \
         deadline:{zero}\n  lifespan:{zero}\n  liveliness: 1\n  \
         liveliness_lease_duration:{zero}\n  avoid_ros_namespace_conventions: false"
    )
}

/// An MCAP file being written. Channels are made on first use; [`Recorder::finish`] writes the
/// summary (a recording not finished is still readable up to its last chunk).
pub struct Recorder {
    path: PathBuf,
    writer: mcap::Writer<BufWriter<File>>,
    channels: BTreeMap<String, u16>,
    sequence: u32,
    options: RecordOptions,
    /// What rosbag2's `metadata.yaml` lists, per CDR channel.
    bag: BTreeMap<u16, BagTopic>,
    /// The first and last log times, nanoseconds.
    span: Option<(u64, u64)>,
}

/// A channel as `metadata.yaml` lists it.
#[derive(Debug)]
struct BagTopic {
    topic: String,
    type_name: String,
    qos: String,
    hash: String,
    count: u64,
}

impl std::fmt::Debug for Recorder {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Recorder")
            .field("path", &self.path)
            .field("channels", &self.channels)
            .finish_non_exhaustive()
    }
}

fn nanos(t: &Time) -> u64 {
    t.nanos().max(0) as u64
}

impl Recorder {
    /// A new recording at `path` (an existing file is replaced): ROS 2 channels only.
    pub fn create(path: &Path) -> Result<Self, RecordError> {
        Self::create_with(path, RecordOptions::default())
    }

    /// A new recording at `path` with `options`.
    pub fn create_with(path: &Path, options: RecordOptions) -> Result<Self, RecordError> {
        let file = File::create(path).map_err(|e| record_error(path, e))?;
        let writer = mcap::WriteOptions::new()
            .profile("ros2")
            .library(concat!("tre ", env!("CARGO_PKG_VERSION")))
            .compression(Some(mcap::Compression::Zstd))
            // On the caller's thread: the robot's cores are the pipeline's.
            .compression_threads(0)
            .create(BufWriter::new(file))
            .map_err(|e| record_error(path, e))?;
        Ok(Self {
            path: path.to_owned(),
            writer,
            channels: BTreeMap::new(),
            sequence: 0,
            options,
            bag: BTreeMap::new(),
            span: None,
        })
    }

    fn channel(
        &mut self,
        topic: &str,
        schema: (&str, &str, &[u8]),
        encoding: &str,
    ) -> Result<u16, RecordError> {
        if let Some(&id) = self.channels.get(topic) {
            return Ok(id);
        }
        let (name, schema_encoding, data) = schema;
        let path = self.path.clone();
        let schema_id = self
            .writer
            .add_schema(name, schema_encoding, data)
            .map_err(|e| record_error(&path, e))?;
        let latched = topic.ends_with("/occupancy");
        let mut metadata =
            BTreeMap::from([("offered_qos_profiles".to_owned(), offered_qos(latched))]);
        // The ROS 2 type hash, where rosbag2's MCAP storage reads it.
        if schema_encoding == "ros2msg" {
            let definition = std::str::from_utf8(data).map_err(|e| record_error(&path, e))?;
            let hash =
                crate::type_hash::rihs01(name, definition).map_err(|e| record_error(&path, e))?;
            metadata.insert("topic_type_hash".to_owned(), hash);
        }
        let bag = (encoding == "cdr").then(|| BagTopic {
            topic: topic.to_owned(),
            type_name: name.to_owned(),
            qos: metadata["offered_qos_profiles"].clone(),
            hash: metadata.get("topic_type_hash").cloned().unwrap_or_default(),
            count: 0,
        });
        let id = self
            .writer
            .add_channel(schema_id, topic, encoding, &metadata)
            .map_err(|e| record_error(&path, e))?;
        self.channels.insert(topic.to_owned(), id);
        if let Some(b) = bag {
            self.bag.insert(id, b);
        }
        Ok(id)
    }

    fn write(
        &mut self,
        channel_id: u16,
        stamp: &Time,
        log_ns: u64,
        data: &[u8],
    ) -> Result<(), RecordError> {
        self.sequence = self.sequence.wrapping_add(1);
        if let Some(b) = self.bag.get_mut(&channel_id) {
            b.count += 1;
        }
        self.span = Some(match self.span {
            Some((a, b)) => (a.min(log_ns), b.max(log_ns)),
            None => (log_ns, log_ns),
        });
        let header = mcap::records::MessageHeader {
            channel_id,
            sequence: self.sequence,
            log_time: log_ns,
            publish_time: nanos(stamp),
        };
        let path = self.path.clone();
        self.writer
            .write_to_known_channel(&header, data)
            .map_err(|e| record_error(&path, e))
    }

    /// Records a ROS 2 message on `topic`, in CDR with its `ros2msg` schema; `stamp` is its
    /// header's, `log_ns` when it was received or sent (nanoseconds since the epoch).
    pub fn ros<M: RosMessage>(
        &mut self,
        topic: &str,
        msg: &M,
        stamp: &Time,
        log_ns: u64,
    ) -> Result<(), RecordError> {
        let definition = M::definition();
        let name = M::schema_name();
        let id = self.channel(topic, (&name, "ros2msg", definition.as_bytes()), "cdr")?;
        let data = to_cdr(msg).map_err(|e| record_error(&self.path.clone(), e))?;
        self.write(id, stamp, log_ns, &data)
    }

    /// Records an image again as `foxglove.RawImage` (JSON) on `topic`, if the recording has
    /// the Foxglove channels ([`RecordOptions::foxglove`]).
    pub fn raw_image(&mut self, topic: &str, img: &Image, log_ns: u64) -> Result<(), RecordError> {
        if !self.options.foxglove {
            return Ok(());
        }
        let id = self.channel(
            topic,
            (
                "foxglove.RawImage",
                "jsonschema",
                RAW_IMAGE_SCHEMA.as_bytes(),
            ),
            "json",
        )?;
        let body = json!({
            "timestamp": stamp_json(&img.header),
            "frame_id": img.header.frame_id,
            "width": img.width,
            "height": img.height,
            "encoding": img.encoding,
            "step": img.step,
            "data": base64::engine::general_purpose::STANDARD.encode(&img.data),
        });
        let stamp = img.header.stamp;
        self.write(id, &stamp, log_ns, body.to_string().as_bytes())
    }

    /// Records the map's layers as `foxglove.Grid` (JSON) on `topic`: one float32 field per
    /// layer, cell (0, 0) at the window's lower-left corner, rows along +y; if the recording
    /// has the Foxglove channels ([`RecordOptions::foxglove`]).
    pub fn grid(
        &mut self,
        topic: &str,
        header: &Header,
        map: &Map,
        layers: &Layers,
        log_ns: u64,
    ) -> Result<(), RecordError> {
        if !self.options.foxglove {
            return Ok(());
        }
        let id = self.channel(
            topic,
            ("foxglove.Grid", "jsonschema", GRID_SCHEMA.as_bytes()),
            "json",
        )?;
        let cfg = map.config();
        let side = cfg.side;
        let all = layers.all();
        let cell_stride = 4 * all.len();
        let mut data = Vec::with_capacity(side * side * cell_stride);
        for iy in 0..side {
            let row = side - 1 - iy;
            for col in 0..side {
                for layer in &all {
                    data.extend(layer[(col, row)].to_le_bytes());
                }
            }
        }
        let (ox, oy) = map.origin();
        let fields: Vec<_> = LAYER_NAMES
            .iter()
            .enumerate()
            .map(|(i, name)| json!({"name": name, "offset": 4 * i, "type": FOXGLOVE_FLOAT32}))
            .collect();
        let body = json!({
            "timestamp": stamp_json(header),
            "frame_id": header.frame_id,
            "pose": {
                "position": {"x": ox as f64 * cfg.cell_m, "y": oy as f64 * cfg.cell_m, "z": 0.0},
                "orientation": {"x": 0.0, "y": 0.0, "z": 0.0, "w": 1.0},
            },
            "column_count": side,
            "cell_size": {"x": cfg.cell_m, "y": cfg.cell_m},
            "row_stride": side * cell_stride,
            "cell_stride": cell_stride,
            "fields": fields,
            "data": base64::engine::general_purpose::STANDARD.encode(&data),
        });
        self.write(id, &header.stamp, log_ns, body.to_string().as_bytes())
    }

    /// Records one frame's inputs and outputs under the [`topics`] of `tre ros2`'s defaults
    /// (prefix `/tre`), each stamped with `f.header`; `log_ns`: when it was received or made.
    pub fn frame(&mut self, f: &FrameRecord<'_>, log_ns: u64) -> Result<(), RecordError> {
        let h = &f.header;
        let stamp = h.stamp;
        if let Some(d) = f.depth_m {
            self.ros(topics::DEPTH, &encode::float_image(h, d), &stamp, log_ns)?;
        }
        match f.colour {
            Some(Colour::Raw(rgb)) => {
                self.ros(topics::COLOUR, &encode::rgb_image(h, rgb), &stamp, log_ns)?;
            }
            Some(Colour::Encoded(bytes)) => {
                let msg = encode::compressed_image(h, bytes);
                self.ros(topics::COLOUR_COMPRESSED, &msg, &stamp, log_ns)?;
            }
            None => {}
        }
        if let Some((k, (w, hgt))) = f.intrinsics {
            let info = encode::camera_info(h, k, w, hgt);
            self.ros(topics::CAMERA_INFO, &info, &stamp, log_ns)?;
        }
        if let Some((pose, world)) = f.pose {
            let header = Header {
                stamp,
                frame_id: world.to_owned(),
            };
            let msg = encode::pose_stamped(&header, pose);
            self.ros(topics::CAMERA_POSE, &msg, &stamp, log_ns)?;
        }
        if let Some(r) = f.roughness_m {
            let img = encode::float_image(h, r);
            self.ros(topics::ROUGHNESS, &img, &stamp, log_ns)?;
            self.raw_image(topics::ROUGHNESS_FOXGLOVE, &img, log_ns)?;
        }
        if let Some(u) = f.uncertainty_m {
            let img = encode::float_image(h, u);
            self.ros(topics::UNCERTAINTY, &img, &stamp, log_ns)?;
        }
        if let Some(t) = f.traversal {
            let img = encode::traversal_image(h, t);
            self.ros(topics::TRAVERSAL, &img, &stamp, log_ns)?;
        }
        Ok(())
    }

    /// Records the map as `grid_map_msgs/GridMap`, `nav_msgs/OccupancyGrid` and
    /// `foxglove.Grid`, under the [`topics`] of `tre ros2`'s defaults.
    pub fn map(
        &mut self,
        header: &Header,
        map: &Map,
        layers: &Layers,
        log_ns: u64,
    ) -> Result<(), RecordError> {
        let stamp = header.stamp;
        let grid = encode::grid_map(header, map, layers);
        self.ros(topics::GRID_MAP, &grid, &stamp, log_ns)?;
        self.grid(topics::GRID_FOXGLOVE, header, map, layers, log_ns)?;
        let occupancy = encode::occupancy(header, map, layers);
        self.ros(topics::OCCUPANCY, &occupancy, &stamp, log_ns)
    }

    /// Writes the summary and closes the file.
    pub fn finish(mut self) -> Result<PathBuf, RecordError> {
        let path = self.path.clone();
        self.writer.finish().map_err(|e| record_error(&path, e))?;
        Ok(path)
    }

    /// Finishes the file and writes rosbag2's `metadata.yaml` (version 8: ROS 2 Iron, Jazzy
    /// and later read it) in its folder, which makes the folder a bag that `ros2 bag info` and
    /// `ros2 bag play` open; `distro` is its `ros_distro`. The folder should hold this
    /// recording alone. Returns the file's path.
    pub fn finish_bag(self, distro: &str) -> Result<PathBuf, RecordError> {
        let yaml = self.bag_metadata(distro);
        let path = self.finish()?;
        let dir = path.parent().unwrap_or(Path::new("."));
        let meta = dir.join("metadata.yaml");
        std::fs::write(&meta, yaml).map_err(|e| record_error(&meta, e))?;
        Ok(path)
    }

    /// rosbag2's `metadata.yaml` of the recording so far.
    fn bag_metadata(&self, distro: &str) -> String {
        let (start, end) = self.span.unwrap_or((0, 0));
        let count: u64 = self.bag.values().map(|b| b.count).sum();
        let file = self
            .path
            .file_name()
            .map(|f| f.to_string_lossy().into_owned())
            .unwrap_or_default();
        let q = |s: &str| serde_json::to_string(s).unwrap_or_default();
        let mut y = format!(
            "rosbag2_bagfile_information:\n  version: 8\n  storage_identifier: mcap\n  \
             duration:\n    nanoseconds: {d}\n  starting_time:\n    \
             nanoseconds_since_epoch: {start}\n  message_count: {count}\n  \
             topics_with_message_count:\n",
            d = end - start
        );
        for b in self.bag.values() {
            y.push_str(&format!(
                "    - topic_metadata:\n        name: {}\n        type: {}\n        \
                 serialization_format: cdr\n        offered_qos_profiles: {}\n        \
                 type_description_hash: {}\n      message_count: {}\n",
                q(&b.topic),
                q(&b.type_name),
                q(&b.qos),
                q(&b.hash),
                b.count
            ));
        }
        y.push_str(&format!(
            "  compression_format: \"\"\n  compression_mode: \"\"\n  relative_file_paths:\n    \
             - {f}\n  files:\n    - path: {f}\n      starting_time:\n        \
             nanoseconds_since_epoch: {start}\n      duration:\n        nanoseconds: {d}\n      \
             message_count: {count}\n  custom_data: ~\n  ros_distro: {distro}\n",
            f = q(&file),
            d = end - start,
            distro = q(distro),
        ));
        y
    }
}

/// The topics of a recording, as `tre ros2` names them by default: its input topics, and its
/// outputs under the prefix `/tre`.
pub mod topics {
    /// Depth in, `32FC1` metres (`16UC1` millimetres from `tre ros2` when the camera sends it).
    pub const DEPTH: &str = "/camera/depth/image_rect_raw";
    /// Colour in, `rgb8`.
    pub const COLOUR: &str = "/camera/color/image_raw";
    /// Colour in as it was sent (PNG or JPEG): `sensor_msgs/CompressedImage`.
    pub const COLOUR_COMPRESSED: &str = "/camera/color/image_raw/compressed";
    /// The intrinsics of the depth (the colour's in the rgb mode).
    pub const CAMERA_INFO: &str = "/camera/depth/camera_info";
    /// The camera's pose in the world, `geometry_msgs/PoseStamped`.
    pub const CAMERA_POSE: &str = "/tre/camera_pose";
    /// Roughness, `32FC1` metres, NaN where there is none.
    pub const ROUGHNESS: &str = "/tre/roughness";
    /// The roughness again as `foxglove.RawImage`.
    pub const ROUGHNESS_FOXGLOVE: &str = "/tre/roughness/foxglove";
    /// Uncertainty, `32FC1` metres.
    pub const UNCERTAINTY: &str = "/tre/uncertainty";
    /// The three-state map, `mono8`: 0 unknown, 1 traversable, 2 hazard.
    pub const TRAVERSAL: &str = "/tre/traversal";
    /// The map, `grid_map_msgs/GridMap`.
    pub const GRID_MAP: &str = "/tre/grid_map";
    /// The map again as `foxglove.Grid`.
    pub const GRID_FOXGLOVE: &str = "/tre/grid/foxglove";
    /// The map's three states, `nav_msgs/OccupancyGrid`.
    pub const OCCUPANCY: &str = "/tre/occupancy";
}

/// A frame's colour as it is recorded.
#[derive(Debug, Clone, Copy)]
pub enum Colour<'a> {
    /// Decoded pixels: `sensor_msgs/Image` `rgb8` on [`topics::COLOUR`].
    Raw(&'a RgbImage),
    /// PNG or JPEG bytes as sent: `sensor_msgs/CompressedImage` on
    /// [`topics::COLOUR_COMPRESSED`].
    Encoded(&'a [u8]),
}

/// One frame's inputs and outputs for [`Recorder::frame`]; what is `None` is not recorded.
#[derive(Debug, Clone, Default)]
pub struct FrameRecord<'a> {
    /// Stamp (the frame's capture time) and the camera's optical frame.
    pub header: Header,
    /// Depth in, metres.
    pub depth_m: Option<&'a Grid<f64>>,
    /// Colour in.
    pub colour: Option<Colour<'a>>,
    /// The pinhole and the image's `(width, height)`.
    pub intrinsics: Option<(&'a Intrinsics, (usize, usize))>,
    /// The camera-to-world pose and the world's frame id.
    pub pose: Option<(&'a MapPose, &'a str)>,
    /// Roughness out, metres.
    pub roughness_m: Option<&'a Grid<f64>>,
    /// Uncertainty out, metres.
    pub uncertainty_m: Option<&'a Grid<f64>>,
    /// The three-state map out.
    pub traversal: Option<&'a Grid<Traversal>>,
}

/// Now, in nanoseconds since the Unix epoch: a message's log time.
pub fn now_ns() -> u64 {
    std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map_or(0, |d| d.as_nanos() as u64)
}

fn stamp_json(h: &Header) -> serde_json::Value {
    json!({"sec": h.stamp.sec, "nsec": h.stamp.nanosec})
}

fn record_error(path: &Path, e: impl Into<RecordFault>) -> RecordError {
    RecordError {
        path: path.to_owned(),
        source: e.into(),
    }
}

/// The MCAP file could not be made or written.
#[derive(Debug, thiserror::Error)]
#[error("recording {}: {source}", path.display())]
pub struct RecordError {
    /// The file.
    pub path: PathBuf,
    /// What failed.
    #[source]
    pub source: RecordFault,
}

/// What failed in making or writing a recording.
#[derive(Debug, thiserror::Error)]
pub enum RecordFault {
    /// The file or the bag's metadata cannot be written.
    #[error(transparent)]
    Io(#[from] std::io::Error),
    /// The MCAP writer failed.
    #[error(transparent)]
    Mcap(#[from] mcap::McapError),
    /// A message does not encode as CDR.
    #[error(transparent)]
    Cdr(#[from] cdr_encoding::Error),
    /// A schema that is not UTF-8.
    #[error(transparent)]
    Utf8(#[from] std::str::Utf8Error),
    /// A schema whose ROS 2 type hash cannot be computed.
    #[error(transparent)]
    TypeHash(#[from] crate::type_hash::TypeHashError),
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]
    use super::*;
    use crate::msgs::{Header, OccupancyGrid};
    use crate::type_hash::rihs01_of;

    /// Every CDR channel names its type hash and QoS where rosbag2's MCAP storage reads them.
    #[test]
    fn channels_carry_the_type_hash_and_qos() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("r.mcap");
        let mut r = Recorder::create(&path).unwrap();
        let h = Header::default();
        let img = Image {
            header: h.clone(),
            ..Image::default()
        };
        r.ros("/tre/roughness", &img, &h.stamp, 1).unwrap();
        r.ros("/tre/occupancy", &OccupancyGrid::default(), &h.stamp, 2)
            .unwrap();
        r.finish().unwrap();
        let bytes = std::fs::read(&path).unwrap();
        let mut seen = BTreeMap::new();
        for m in mcap::MessageStream::new(&bytes).unwrap() {
            let c = m.unwrap().channel;
            seen.insert(c.topic.clone(), c.metadata.clone());
        }
        let hash = |t: &str| seen[t]["topic_type_hash"].clone();
        assert_eq!(hash("/tre/roughness"), rihs01_of::<Image>().unwrap());
        assert_eq!(
            hash("/tre/occupancy"),
            rihs01_of::<OccupancyGrid>().unwrap()
        );
        assert!(seen["/tre/occupancy"]["offered_qos_profiles"].contains("durability: 1"));
    }

    /// `finish_bag` writes rosbag2's `metadata.yaml`: each CDR topic with its type, QoS, type
    /// hash and count, and the file.
    #[test]
    fn a_bag_folder_lists_its_topics() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("run.mcap");
        let mut r = Recorder::create(&path).unwrap();
        let h = Header::default();
        for ns in [1_000, 3_000] {
            r.ros("/tre/roughness", &Image::default(), &h.stamp, ns)
                .unwrap();
        }
        r.ros("/tre/occupancy", &OccupancyGrid::default(), &h.stamp, 2_000)
            .unwrap();
        r.finish_bag("jazzy").unwrap();
        let y = std::fs::read_to_string(dir.path().join("metadata.yaml")).unwrap();
        for want in [
            "  version: 8\n",
            "  storage_identifier: mcap\n",
            "  message_count: 3\n",
            "    nanoseconds: 2000\n",
            "nanoseconds_since_epoch: 1000\n",
            "name: \"/tre/roughness\"\n        type: \"sensor_msgs/msg/Image\"",
            "      message_count: 2\n",
            "    - path: \"run.mcap\"\n",
            "  ros_distro: \"jazzy\"\n",
        ] {
            assert!(y.contains(want), "{want:?} not in {y}");
        }
        let hash = rihs01_of::<OccupancyGrid>().unwrap();
        assert!(
            y.contains(&format!("type_description_hash: \"{hash}\"")),
            "{y}"
        );
    }
}
