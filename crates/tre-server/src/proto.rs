//! The edge between the stream's protobuf messages and the service's domain types: `TryFrom`
//! conversions whose errors name the bad field, and the builders of server messages.

use prost::Message;

use super::error::{ApiError, CameraError, OptionError, RequestError, StreamError};
use super::map::{settings_from_pb, MapSettings};
use super::options::FrameOptions;
use super::request::{FrameReply, FrameRequest, SCALE_M};
use tre_core::kinds::MapFormat;
use tre_core::map::Pose;
use tre_core::roughness::noise::SensorNoise;
use tre_io::{CameraFile, SensorSpec};
use tre_pipeline::{check_dsac_hypotheses, Traversability};
use tre_proto::v1 as pb;

/// A stream's settings from its Hello.
#[derive(Debug, Clone, Default)]
pub(crate) struct StreamSettings {
    /// Camera of every frame that does not bring its own.
    pub camera: Option<CameraFile>,
    /// Options of every frame.
    pub options: FrameOptions,
    /// The stream's grid map, if asked for.
    pub map: Option<MapSettings>,
}

/// A frame from the stream, with the fields echoed in its answer.
#[derive(Debug, Clone)]
pub(crate) struct StreamFrame {
    /// The client's sequence number.
    pub sequence: u64,
    /// The client's timestamp, echoed.
    pub timestamp_us: i64,
    /// The frame's own camera, overriding the Hello's.
    pub camera: Option<CameraFile>,
    /// Encoded image (empty: none).
    pub image: Vec<u8>,
    /// Encoded depth (empty: none).
    pub depth: Vec<u8>,
    /// Camera-to-world pose for the map.
    pub pose: Option<Pose>,
}

impl StreamFrame {
    /// The request to run, given the stream's settings.
    pub(crate) fn into_request(self, settings: &StreamSettings) -> FrameRequest {
        FrameRequest {
            rgb: (!self.image.is_empty()).then_some(self.image),
            depth: (!self.depth.is_empty()).then_some(self.depth),
            camera: self.camera.or_else(|| settings.camera.clone()),
            options: settings.options,
            map: None,
        }
    }
}

/// What a client message turns into.
#[derive(Debug)]
pub(crate) enum Incoming {
    /// New settings.
    Hello(StreamSettings),
    /// A frame.
    Frame(StreamFrame),
}

/// The camera message's sensor: coefficients when given, else the name (a preset, or a
/// description).
fn sensor_from_pb(
    name: Option<String>,
    sigma_mm: &[f64],
) -> Result<Option<SensorSpec>, RequestError> {
    match (sigma_mm, name) {
        ([], None) => Ok(None),
        ([], Some(n)) => Ok(Some(SensorSpec::from_json(n.into())?)),
        (&[a, b, c], _) => SensorNoise::coefficients([a, b, c])
            .map(|m| Some(SensorSpec::Model(m)))
            .map_err(|e| CameraError::SensorCoefficients(e).into()),
        (other, _) => Err(CameraError::SensorCoefficientCount { given: other.len() }.into()),
    }
}

/// A stream message's camera as the camera file it stands for (the same checks as a file).
fn camera_from_pb(c: pb::Camera) -> Result<CameraFile, RequestError> {
    let cam = CameraFile {
        fx: c.fx,
        fy: c.fy,
        cx: c.cx,
        cy: c.cy,
        width: c.width.map(|w| w as usize),
        height: c.height.map(|h| h as usize),
        depth_scale: c.depth_scale,
        pitch_deg: c.pitch_deg,
        height_m: c.height_m,
        sensor: sensor_from_pb(c.sensor, &c.sensor_sigma_mm)?,
    };
    cam.intrinsics().map_err(CameraError::Geometry)?;
    cam.mounting().map_err(CameraError::Geometry)?;
    // The stated size is checked against each frame's; the side limit is the frame's.
    let ranges = super::request::DecodeLimits {
        max_side: usize::MAX,
        ..super::request::DecodeLimits::default()
    };
    super::request::check_camera_ranges(&cam, ranges)?;
    if let Some(s) = cam.depth_scale.filter(|s| !(s.is_finite() && *s > 0.0)) {
        return Err(CameraError::DepthScale {
            field: "camera.depth_scale:",
            scale: s,
        }
        .into());
    }
    Ok(cam)
}

/// The Hello's map settings, checked, with the noise model the map's variance needs (the
/// Hello's `sensor` or the camera's).
fn hello_map(
    map: Option<&pb::MapSettings>,
    sensor: Option<&SensorNoise>,
    camera: Option<&CameraFile>,
) -> Result<Option<MapSettings>, RequestError> {
    let Some(m) = map else {
        return Ok(None);
    };
    let camera_model = camera
        .and_then(|c| c.sensor.as_ref())
        .and_then(SensorSpec::noise);
    if sensor.is_none() && camera_model.is_none() {
        return Err(OptionError::MapWithoutSensor.into());
    }
    settings_from_pb(m).map(Some)
}

impl TryFrom<pb::Hello> for StreamSettings {
    type Error = RequestError;

    fn try_from(h: pb::Hello) -> Result<Self, RequestError> {
        let unknown = |field, value| OptionError::UnknownValue { field, value };
        let mode = pb::Mode::try_from(h.mode).map_err(|_| unknown("hello.mode", h.mode))?;
        let format =
            pb::Format::try_from(h.format).map_err(|_| unknown("hello.format", h.format))?;
        let normals =
            pb::Normals::try_from(h.normals).map_err(|_| unknown("hello.normals", h.normals))?;
        let dsac_hypotheses = match h.dsac_hypotheses {
            0 => None,
            k => Some(
                check_dsac_hypotheses(k).map_err(|e| OptionError::DsacHypotheses {
                    field: "hello.dsac_hypotheses",
                    source: Box::new(e),
                })?,
            ),
        };
        if let Some(m) = h.preview_max_m.filter(|m| !(m.is_finite() && *m > 0.0)) {
            return Err(OptionError::PreviewMax {
                field: "hello.preview_max_m",
                value: m,
            }
            .into());
        }
        let sensor = match sensor_from_pb(h.sensor, &h.sensor_sigma_mm) {
            Ok(None) => None,
            Ok(Some(SensorSpec::Model(m))) => Some(m),
            Ok(Some(SensorSpec::Description(description))) => {
                return Err(OptionError::SensorDescription { description }.into())
            }
            Err(e) => {
                return Err(OptionError::Sensor {
                    field: "hello.sensor",
                    source: Box::new(e),
                }
                .into())
            }
        };
        let camera = h.camera.map(camera_from_pb).transpose()?;
        let map = hello_map(h.map.as_ref(), sensor.as_ref(), camera.as_ref())?;
        Ok(Self {
            camera,
            map,
            options: FrameOptions {
                sensor,
                mode: mode.into(),
                format: MapFormat::from(format),
                seed: h.seed,
                normals: normals.into(),
                dsac_hypotheses,
                preview_max_m: h.preview_max_m,
                traversable_bytes: h.want_traversable,
                traversal_bytes: h.want_traversal,
                uncertainty_f32: h.want_uncertainty,
                traversability: Traversability::from_cm_deg(h.max_roughness_cm, h.max_slope_deg)
                    .map_err(|source| OptionError::Traversability {
                        prefix: "hello.",
                        source,
                    })?,
                ..FrameOptions::default()
            },
        })
    }
}

impl TryFrom<pb::Frame> for StreamFrame {
    type Error = RequestError;

    fn try_from(f: pb::Frame) -> Result<Self, RequestError> {
        if f.image.is_empty() && f.depth.is_empty() {
            return Err(StreamError::EmptyFrame.into());
        }
        let pose = match f.pose.as_slice() {
            [] => None,
            v => Some(Pose::from_row_major(v).map_err(StreamError::Pose)?),
        };
        Ok(Self {
            sequence: f.sequence,
            timestamp_us: f.timestamp_us,
            pose,
            camera: f.camera.map(camera_from_pb).transpose()?,
            image: f.image,
            depth: f.depth,
        })
    }
}

/// Decodes one binary WebSocket message from a client. The error carries the frame's sequence
/// number when the message was a frame.
pub(crate) fn decode_client(bytes: &[u8]) -> Result<Incoming, (Option<u64>, RequestError)> {
    let msg =
        pb::ClientMessage::decode(bytes).map_err(|e| (None, StreamError::NotAMessage(e).into()))?;
    match msg.msg {
        Some(pb::client_message::Msg::Hello(h)) => StreamSettings::try_from(h)
            .map(Incoming::Hello)
            .map_err(|e| (None, e)),
        Some(pb::client_message::Msg::Frame(f)) => {
            let seq = f.sequence;
            StreamFrame::try_from(f)
                .map(Incoming::Frame)
                .map_err(|e| (Some(seq), e))
        }
        None => Err((None, StreamError::EmptyMessage.into())),
    }
}

/// The sequence number of a frame message, read without decoding the rest (for a message too
/// large to decode, so that its error can still name the frame); `None` when `bytes` does not
/// hold a frame. Decoding stays with [`decode_client`].
pub(crate) fn peek_frame_sequence(mut bytes: &[u8]) -> Option<u64> {
    use prost::encoding::{decode_key, decode_varint, WireType};
    /// Skips one field's value of `wire` type.
    fn skip(buf: &mut &[u8], wire: WireType) -> Option<()> {
        let n = match wire {
            WireType::Varint => return decode_varint(buf).ok().map(drop),
            WireType::SixtyFourBit => 8,
            WireType::ThirtyTwoBit => 4,
            WireType::LengthDelimited => usize::try_from(decode_varint(buf).ok()?).ok()?,
            WireType::StartGroup | WireType::EndGroup => return None,
        };
        *buf = buf.get(n..)?;
        Some(())
    }
    while !bytes.is_empty() {
        let (tag, wire) = decode_key(&mut bytes).ok()?;
        if tag == 2 && wire == WireType::LengthDelimited {
            // ClientMessage.frame: its sequence is field 1 (0 when absent, as proto3 decodes).
            let len = usize::try_from(decode_varint(&mut bytes).ok()?).ok()?;
            let mut frame = bytes.get(..len)?;
            while !frame.is_empty() {
                let (tag, wire) = decode_key(&mut frame).ok()?;
                if tag == 1 && wire == WireType::Varint {
                    return decode_varint(&mut frame).ok();
                }
                skip(&mut frame, wire)?;
            }
            return Some(0);
        }
        skip(&mut bytes, wire)?;
    }
    None
}

fn encode(msg: pb::server_message::Msg) -> Vec<u8> {
    pb::ServerMessage { msg: Some(msg) }.encode_to_vec()
}

/// The Ready message.
pub(crate) fn ready(max_message_bytes: usize, models: Vec<String>, stream_id: &str) -> Vec<u8> {
    encode(pb::server_message::Msg::Ready(pb::Ready {
        max_message_bytes: max_message_bytes as u64,
        models,
        stream_id: stream_id.to_owned(),
    }))
}

/// A MapUpdate message.
pub(crate) fn map_update(update: pb::MapUpdate) -> Vec<u8> {
    encode(pb::server_message::Msg::Map(update))
}

/// An Error message.
pub(crate) fn error(sequence: Option<u64>, e: &ApiError) -> Vec<u8> {
    encode(pb::server_message::Msg::Error(pb::Error {
        sequence,
        code: e.code.as_str().to_owned(),
        message: e.message.clone(),
    }))
}

/// A Dropped message.
pub(crate) fn dropped(sequence: u64, dropped_total: u64) -> Vec<u8> {
    encode(pb::server_message::Msg::Dropped(pb::Dropped {
        sequence,
        dropped_total,
    }))
}

/// A Result message for `frame`'s answer.
pub(crate) fn result(
    sequence: u64,
    timestamp_us: i64,
    reply: FrameReply,
    latency_ms: f64,
    dropped_total: u64,
) -> Vec<u8> {
    let format = pb::Format::from(reply.format);
    encode(pb::server_message::Msg::Result(pb::Result {
        sequence,
        timestamp_us,
        width: reply.size.0 as u32,
        height: reply.size.1 as u32,
        format: format as i32,
        scale_m: SCALE_M,
        roughness: reply.roughness,
        traversable: reply.traversable,
        traversal: reply.traversal,
        uncertainty: reply.uncertainty,
        timings: reply
            .timings
            .iter()
            .map(|(stage, d)| pb::StageTiming {
                stage: stage.to_owned(),
                ms: d.as_secs_f64() * 1e3,
            })
            .collect(),
        latency_ms,
        dropped_total,
        mode: reply.mode.to_string(),
        assumed: reply.assumed.iter().map(|a| a.key().to_owned()).collect(),
        gravity: reply.gravity.to_string(),
    }))
}

#[cfg(test)]
mod tests {
    use super::*;
    use tre_proto::ErrorCode;

    #[test]
    fn the_sequence_of_a_frame_is_read_without_decoding_it() {
        let frame = |sequence| {
            pb::ClientMessage {
                msg: Some(pb::client_message::Msg::Frame(pb::Frame {
                    sequence,
                    timestamp_us: -5,
                    image: vec![7; 300],
                    depth: vec![1; 20],
                    ..Default::default()
                })),
            }
            .encode_to_vec()
        };
        for seq in [0, 1, 300, u64::MAX] {
            assert_eq!(peek_frame_sequence(&frame(seq)), Some(seq));
        }
        // Fields in another order still work.
        let mut reordered = Vec::new();
        prost::encoding::bytes::encode(3, &vec![9u8; 40], &mut reordered);
        prost::encoding::uint64::encode(1, &42, &mut reordered);
        let mut outer = Vec::new();
        prost::encoding::bytes::encode(2, &reordered, &mut outer);
        assert_eq!(peek_frame_sequence(&outer), Some(42));
        let hello = pb::ClientMessage {
            msg: Some(pb::client_message::Msg::Hello(pb::Hello::default())),
        };
        assert_eq!(peek_frame_sequence(&hello.encode_to_vec()), None);
        assert_eq!(peek_frame_sequence(&[0xFF, 0xFF, 0xFF]), None);
        assert_eq!(peek_frame_sequence(&frame(5)[..10]), None);
    }

    #[test]
    fn garbage_is_a_bad_request() {
        let (seq, e) = decode_client(&[0xFF, 0xFF, 0xFF, 0x01, 0x02]).unwrap_err();
        assert_eq!((seq, e.code()), (None, ErrorCode::BadRequest));
    }

    #[test]
    fn nonsense_camera_names_the_field() {
        let hello = pb::ClientMessage {
            msg: Some(pb::client_message::Msg::Hello(pb::Hello {
                camera: Some(pb::Camera {
                    fx: -1.0,
                    fy: 500.0,
                    cx: 1.0,
                    cy: 1.0,
                    ..Default::default()
                }),
                ..Default::default()
            })),
        };
        let (_, e) = decode_client(&hello.encode_to_vec()).unwrap_err();
        assert_eq!(e.code(), ErrorCode::BadCamera);
        assert!(e.to_string().starts_with("camera"), "{e}");
    }

    #[test]
    fn an_empty_frame_is_refused_with_its_sequence() {
        let frame = pb::ClientMessage {
            msg: Some(pb::client_message::Msg::Frame(pb::Frame {
                sequence: 9,
                ..Default::default()
            })),
        };
        let (seq, e) = decode_client(&frame.encode_to_vec()).unwrap_err();
        assert_eq!((seq, e.code()), (Some(9), ErrorCode::BadRequest));
    }
}
