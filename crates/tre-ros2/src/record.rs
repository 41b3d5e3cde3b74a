//! Recordings as MCAP: every message in its ROS 2 type (`ros2msg` schema, CDR), which
//! `ros2 bag`, Foxglove and the `mcap` tools read, and the outputs again in Foxglove's own
//! schemas (`foxglove.RawImage`, `foxglove.Grid`; JSON), which Foxglove shows with no
//! extension (docs/ros2.md says which viewer shows which channel).

use std::collections::BTreeMap;
use std::fs::File;
use std::io::BufWriter;
use std::path::{Path, PathBuf};

use base64::Engine as _;
use serde_json::json;
use tre_core::map::{GridMap as Map, Layers, LAYER_NAMES};

use crate::error::Ros2Error;
use crate::msgs::{to_cdr, Header, Image, RosMessage, Time};

/// JSON Schema of `foxglove.RawImage` (the fields this writer fills).
const RAW_IMAGE_SCHEMA: &str = r#"{"title":"foxglove.RawImage","type":"object","properties":{"timestamp":{"type":"object","properties":{"sec":{"type":"integer"},"nsec":{"type":"integer"}}},"frame_id":{"type":"string"},"width":{"type":"integer"},"height":{"type":"integer"},"encoding":{"type":"string"},"step":{"type":"integer"},"data":{"type":"string","contentEncoding":"base64"}}}"#;

/// JSON Schema of `foxglove.Grid` (the fields this writer fills).
const GRID_SCHEMA: &str = r#"{"title":"foxglove.Grid","type":"object","properties":{"timestamp":{"type":"object","properties":{"sec":{"type":"integer"},"nsec":{"type":"integer"}}},"frame_id":{"type":"string"},"pose":{"type":"object","properties":{"position":{"type":"object","properties":{"x":{"type":"number"},"y":{"type":"number"},"z":{"type":"number"}}},"orientation":{"type":"object","properties":{"x":{"type":"number"},"y":{"type":"number"},"z":{"type":"number"},"w":{"type":"number"}}}}},"column_count":{"type":"integer"},"cell_size":{"type":"object","properties":{"x":{"type":"number"},"y":{"type":"number"}}},"row_stride":{"type":"integer"},"cell_stride":{"type":"integer"},"fields":{"type":"array","items":{"type":"object","properties":{"name":{"type":"string"},"offset":{"type":"integer"},"type":{"type":"integer"}}}},"data":{"type":"string","contentEncoding":"base64"}}}"#;

/// `foxglove.NumericType` of a float32 field.
const FOXGLOVE_FLOAT32: u32 = 7;

/// An MCAP file being written. Channels are made on first use; [`Recorder::finish`] writes the
/// summary (a recording not finished is still readable up to its last chunk).
pub struct Recorder {
    path: PathBuf,
    writer: mcap::Writer<BufWriter<File>>,
    channels: BTreeMap<String, u16>,
    sequence: u32,
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
    /// A new recording at `path` (an existing file is replaced).
    pub fn create(path: &Path) -> Result<Self, Ros2Error> {
        let file = File::create(path).map_err(|e| record_error(path, e))?;
        let writer = mcap::WriteOptions::new()
            .profile("ros2")
            .library(concat!("tre ", env!("CARGO_PKG_VERSION")))
            .create(BufWriter::new(file))
            .map_err(|e| record_error(path, e))?;
        Ok(Self {
            path: path.to_owned(),
            writer,
            channels: BTreeMap::new(),
            sequence: 0,
        })
    }

    fn channel(
        &mut self,
        topic: &str,
        schema: (&str, &str, &[u8]),
        encoding: &str,
    ) -> Result<u16, Ros2Error> {
        if let Some(&id) = self.channels.get(topic) {
            return Ok(id);
        }
        let (name, schema_encoding, data) = schema;
        let path = self.path.clone();
        let schema_id = self
            .writer
            .add_schema(name, schema_encoding, data)
            .map_err(|e| record_error(&path, e))?;
        let id = self
            .writer
            .add_channel(schema_id, topic, encoding, &BTreeMap::new())
            .map_err(|e| record_error(&path, e))?;
        self.channels.insert(topic.to_owned(), id);
        Ok(id)
    }

    fn write(
        &mut self,
        channel_id: u16,
        stamp: &Time,
        log_ns: u64,
        data: &[u8],
    ) -> Result<(), Ros2Error> {
        self.sequence = self.sequence.wrapping_add(1);
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
    ) -> Result<(), Ros2Error> {
        let definition = M::definition();
        let name = M::schema_name();
        let id = self.channel(topic, (&name, "ros2msg", definition.as_bytes()), "cdr")?;
        let data = to_cdr(msg).map_err(|e| record_error(&self.path.clone(), e))?;
        self.write(id, stamp, log_ns, &data)
    }

    /// Records an image again as `foxglove.RawImage` (JSON) on `topic`.
    pub fn raw_image(&mut self, topic: &str, img: &Image, log_ns: u64) -> Result<(), Ros2Error> {
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
    /// layer, cell (0, 0) at the window's lower-left corner, rows along +y.
    pub fn grid(
        &mut self,
        topic: &str,
        header: &Header,
        map: &Map,
        layers: &Layers,
        log_ns: u64,
    ) -> Result<(), Ros2Error> {
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

    /// Writes the summary and closes the file.
    pub fn finish(mut self) -> Result<PathBuf, Ros2Error> {
        let path = self.path.clone();
        self.writer.finish().map_err(|e| record_error(&path, e))?;
        Ok(path)
    }
}

fn stamp_json(h: &Header) -> serde_json::Value {
    json!({"sec": h.stamp.sec, "nsec": h.stamp.nanosec})
}

fn record_error(path: &Path, e: impl std::fmt::Display) -> Ros2Error {
    Ros2Error::Record {
        path: path.display().to_string(),
        message: e.to_string(),
    }
}
