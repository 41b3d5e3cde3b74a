//! The client's edge with the stream protocol: domain types to `roughness.v1` messages and
//! back (functions and `From` / `TryFrom`, errors naming the bad field). Nothing else in the client sees a
//! protobuf type.

use std::time::Duration;

use image::{DynamicImage, ImageFormat};
use prost::Message;

use super::clock::Stamp;
use super::config::ClientConfig;
use super::error::{MapProblem, MapUpdateProblem, ProtocolProblem, ResultProblem};
use super::event::{ErrorKind, Event, Frame, FrameResult, Roughness, ServerInfo, StreamMap};
use super::ClientError;
use tre_core::geometry::Grid;
use tre_core::kinds::MapFormat;
use tre_core::map::Layers;
use tre_core::roughness::noise::SensorNoise;
use tre_core::roughness::traversal::Traversal;
use tre_io::{self as io, CameraFile, ROUGHNESS_PNG_SCALE_M};
use tre_proto::v1 as pb;

/// A camera file as the stream message that carries it.
fn pb_camera(c: &CameraFile) -> pb::Camera {
    pb::Camera {
        fx: c.fx,
        fy: c.fy,
        cx: c.cx,
        cy: c.cy,
        pitch_deg: c.pitch_deg,
        height_m: c.height_m,
        depth_scale: c.depth_scale,
        width: c.width.map(|w| u32::try_from(w).unwrap_or(u32::MAX)),
        height: c.height.map(|h| u32::try_from(h).unwrap_or(u32::MAX)),
        sensor: match &c.sensor {
            Some(io::SensorSpec::Model(SensorNoise::Preset(p))) => Some(p.name().to_string()),
            Some(io::SensorSpec::Description(d)) => Some(d.clone()),
            _ => None,
        },
        sensor_sigma_mm: match &c.sensor {
            Some(io::SensorSpec::Model(SensorNoise::Coefficients { sigma_mm })) => {
                sigma_mm.to_vec()
            }
            Some(io::SensorSpec::Model(SensorNoise::Stereo { stereo })) => {
                stereo.sigma_mm().to_vec()
            }
            _ => Vec::new(),
        },
    }
}

impl From<&ClientConfig> for pb::Hello {
    fn from(cfg: &ClientConfig) -> Self {
        Self {
            camera: cfg.camera.as_ref().map(pb_camera),
            mode: pb::Mode::from(cfg.mode) as i32,
            format: pb::Format::from(cfg.format) as i32,
            seed: cfg.seed,
            preview_max_m: cfg.preview_max_m,
            want_traversable: cfg.want_traversable,
            want_traversal: cfg.want_traversal,
            want_uncertainty: cfg.want_traversal,
            normals: pb::Normals::from(cfg.normals) as i32,
            dsac_hypotheses: cfg.dsac_hypotheses.unwrap_or(0),
            max_roughness_cm: cfg.max_roughness_cm,
            max_slope_deg: cfg.max_slope_deg,
            map: cfg.map.map(|m| pb::MapSettings {
                cell_m: m.cell_m,
                side: m.side,
                send_hz: 0.0,
                gravity: m.gravity.map(|g| g.to_vec()).unwrap_or_default(),
            }),
            sensor: match cfg.sensor {
                Some(SensorNoise::Preset(p)) => Some(p.to_string()),
                _ => None,
            },
            sensor_sigma_mm: match cfg.sensor {
                Some(SensorNoise::Coefficients { sigma_mm }) => sigma_mm.to_vec(),
                Some(SensorNoise::Stereo { stereo }) => stereo.sigma_mm().to_vec(),
                _ => Vec::new(),
            },
        }
    }
}

/// A byte map (`traversable`, `traversal`) as a grid of `cell`s of its bytes; none: `None`.
fn decode_bytes<T>(
    map: &'static str,
    bytes: &[u8],
    (w, h): (usize, usize),
    cell: impl Fn(u8) -> Result<T, ResultProblem>,
) -> Result<Option<Grid<T>>, ResultProblem> {
    if bytes.is_empty() {
        return Ok(None);
    }
    if bytes.len() != w * h {
        return Err(ResultProblem::ByteCount {
            map,
            bytes: bytes.len(),
            width: w,
            height: h,
        });
    }
    let cells = bytes.iter().map(|&b| cell(b)).collect::<Result<_, _>>()?;
    Grid::from_vec(w, h, cells)
        .map(Some)
        .map_err(|e| ResultProblem::Map {
            map,
            reason: MapProblem::Grid(e),
        })
}

/// The three-state map from its bytes (0 unknown, 1 traversable, 2 hazard; none: `None`).
fn decode_traversal(
    bytes: &[u8],
    size: (usize, usize),
) -> Result<Option<Grid<Traversal>>, ResultProblem> {
    decode_bytes("traversal", bytes, size, |b| match b {
        0 => Ok(Traversal::Unknown),
        1 => Ok(Traversal::Traversable),
        2 => Ok(Traversal::Hazard),
        other => Err(ResultProblem::TraversalByte(other)),
    })
}

/// The encoded Hello for `cfg`.
pub(crate) fn hello(cfg: &ClientConfig) -> Vec<u8> {
    let msg = pb::client_message::Msg::Hello(pb::Hello::from(cfg));
    pb::ClientMessage { msg: Some(msg) }.encode_to_vec()
}

/// The encoded Frame message for `frame` as `sequence`, stamped `timestamp_us`.
pub(crate) fn frame(frame: Frame, sequence: u64, timestamp_us: i64) -> Vec<u8> {
    let msg = pb::client_message::Msg::Frame(pb::Frame {
        sequence,
        timestamp_us: frame.timestamp_us.unwrap_or(timestamp_us),
        image: frame.image,
        depth: frame.depth.unwrap_or_default(),
        camera: frame.camera.as_ref().map(pb_camera),
        pose: frame.pose.unwrap_or_default(),
    });
    pb::ClientMessage { msg: Some(msg) }.encode_to_vec()
}

/// A Result as received: its map is decoded once the client knows the latency.
#[derive(Debug)]
pub(crate) struct WireResult(pb::Result);

impl WireResult {
    /// The frame's sequence number.
    pub(crate) fn sequence(&self) -> u64 {
        self.0.sequence
    }
}

/// A server message in domain terms.
#[derive(Debug)]
pub(crate) enum Incoming {
    Ready(ServerInfo),
    Result(WireResult),
    /// [`Event::Dropped`], [`Event::Error`] or [`Event::Map`], as the session reports it.
    Event(Event),
}

impl Incoming {
    /// The message's name, as a protocol error tells it.
    pub(crate) fn name(&self) -> &'static str {
        match self {
            Self::Ready(_) => "Ready",
            Self::Result(_) => "Result",
            Self::Event(Event::Dropped { .. }) => "Dropped",
            Self::Event(Event::Map(_)) => "Map",
            Self::Event(_) => "Error",
        }
    }
}

impl TryFrom<pb::ServerMessage> for Incoming {
    type Error = ClientError;

    fn try_from(m: pb::ServerMessage) -> Result<Self, ClientError> {
        use pb::server_message::Msg;
        Ok(match m.msg {
            Some(Msg::Ready(r)) => Self::Ready(ServerInfo {
                max_message_bytes: usize::try_from(r.max_message_bytes).unwrap_or(usize::MAX),
                models: r.models,
            }),
            Some(Msg::Result(r)) => Self::Result(WireResult(r)),
            Some(Msg::Dropped(d)) => Self::Event(Event::Dropped {
                sequence: d.sequence,
                dropped_total: d.dropped_total,
            }),
            Some(Msg::Error(e)) => Self::Event(Event::Error {
                sequence: e.sequence,
                code: ErrorKind::from_wire(&e.code),
                message: e.message,
            }),
            Some(Msg::Map(m)) => Self::Event(Event::Map(Box::new(stream_map(m)?))),
            None => return Err(ClientError::Protocol(ProtocolProblem::Empty)),
        })
    }
}

/// A MapUpdate in domain terms: its nine layers by name, each `side × side` float32.
fn stream_map(m: pb::MapUpdate) -> Result<StreamMap, ClientError> {
    let bad = |why| ClientError::Protocol(ProtocolProblem::BadMap(why));
    let side = m.side as usize;
    let map_from_world: [f64; 9] = m
        .map_from_world
        .as_slice()
        .try_into()
        .map_err(|_| bad(MapUpdateProblem::Transform(m.map_from_world.len())))?;
    let layer = |name: &'static str| -> Result<Grid<f32>, ClientError> {
        let l = m
            .layers
            .iter()
            .find(|l| l.name == name)
            .ok_or_else(|| bad(MapUpdateProblem::NoLayer(name)))?;
        if l.data.len() != 4 * side * side {
            return Err(bad(MapUpdateProblem::LayerSize {
                name,
                bytes: l.data.len(),
                side,
            }));
        }
        let cells = l
            .data
            .chunks_exact(4)
            .map(|b| f32::from_le_bytes([b[0], b[1], b[2], b[3]]))
            .collect();
        Grid::from_vec(side, side, cells)
            .map_err(|reason| bad(MapUpdateProblem::Grid { name, reason }))
    };
    let layers = Layers {
        elevation: layer("elevation")?,
        variance: layer("variance")?,
        count: layer("count")?,
        // Newer layers: a server from before them sends none, read as no data.
        upper: layer("upper").unwrap_or_else(|_| Grid::new(side, side, f32::NAN)),
        clearance: layer("clearance").unwrap_or_else(|_| Grid::new(side, side, f32::NAN)),
        roughness: layer("roughness")?,
        slope: layer("slope")?,
        step: layer("step")?,
        score: layer("score")?,
        traversal: layer("traversal")?,
        last_update: layer("last_update")?,
    };
    Ok(StreamMap {
        sequence: m.sequence,
        cell_m: m.cell_m,
        side,
        origin: (m.origin_x, m.origin_y),
        map_from_world,
        layers,
        fused: m.fused,
        skipped: m.skipped,
    })
}

/// Decodes one binary WebSocket message from the server.
pub(crate) fn decode_server(bytes: &[u8]) -> Result<Incoming, ClientError> {
    let msg = pb::ServerMessage::decode(bytes)
        .map_err(|e| ClientError::Protocol(ProtocolProblem::Decode(e)))?;
    Incoming::try_from(msg)
}

impl TryFrom<(WireResult, Stamp)> for FrameResult {
    type Error = ClientError;

    /// The result with its map decoded, its frame having been stamped `sent`: the latency runs
    /// to the end of the decoding.
    fn try_from((WireResult(r), sent): (WireResult, Stamp)) -> Result<Self, ClientError> {
        let sequence = r.sequence;
        let bad = |reason| ClientError::BadResult { sequence, reason };
        let in_map = |map| move |reason| bad(ResultProblem::Map { map, reason });
        let (w, h) = (r.width as usize, r.height as usize);
        if w == 0 || h == 0 {
            return Err(bad(ResultProblem::ZeroSize {
                width: w,
                height: h,
            }));
        }
        let format = pb::Format::try_from(r.format)
            .map(MapFormat::from)
            .map_err(|_| bad(ResultProblem::UnknownFormat(r.format)))?;
        let roughness =
            decode_map(&r.roughness, format, r.scale_m, (w, h)).map_err(in_map("roughness"))?;
        let traversable =
            decode_bytes("traversable", &r.traversable, (w, h), |t| Ok(t != 0)).map_err(bad)?;
        let traversal = decode_traversal(&r.traversal, (w, h)).map_err(bad)?;
        let uncertainty_m = match r.uncertainty.len() {
            0 => None,
            _ => match decode_map(&r.uncertainty, MapFormat::F32, r.scale_m, (w, h)) {
                Ok(Roughness::Metres(m)) => Some(m),
                Ok(Roughness::Colour(_)) => None,
                Err(e) => return Err(in_map("uncertainty")(e)),
            },
        };
        let ms = |field, ms: f64| {
            Duration::try_from_secs_f64(ms / 1e3)
                .map_err(|_| bad(ResultProblem::Duration { field, ms }))
        };
        let timings = r
            .timings
            .iter()
            .map(|t| Ok((t.stage.clone(), ms("timings", t.ms)?)))
            .collect::<Result<_, ClientError>>()?;
        let server_latency = ms("latency_ms", r.latency_ms)?;
        let received = Stamp::now();
        Ok(Self {
            sequence,
            timestamp_us: r.timestamp_us,
            width: w,
            height: h,
            roughness,
            encoded: r.roughness,
            format,
            traversable,
            traversal,
            uncertainty_m,
            timings,
            latency: received.at.saturating_duration_since(sent.at),
            sent_unix_us: sent.unix_us,
            received_unix_us: received.unix_us,
            server_latency,
            dropped_total: r.dropped_total,
            mode: r.mode,
            assumed: r.assumed,
            gravity: r.gravity,
        })
    }
}

/// Decodes a map of a Result and checks its size.
fn decode_map(
    bytes: &[u8],
    format: MapFormat,
    scale_m: f64,
    (w, h): (usize, usize),
) -> Result<Roughness, MapProblem> {
    let png = || {
        image::load_from_memory_with_format(bytes, ImageFormat::Png)
            .map_err(|e| MapProblem::Png(Box::new(e)))
    };
    let check = |(iw, ih): (u32, u32)| {
        if (iw as usize, ih as usize) == (w, h) {
            Ok(())
        } else {
            Err(MapProblem::SizeMismatch {
                image: (iw, ih),
                frame: (w, h),
            })
        }
    };
    match format {
        MapFormat::Png16 => {
            let img = png()?;
            if !matches!(img, DynamicImage::ImageLumaA16(_)) {
                return Err(MapProblem::NotGreyAlpha16(img.color()));
            }
            check((img.width(), img.height()))?;
            let mut m = io::decode_roughness_png16(&img);
            if scale_m > 0.0 && scale_m != ROUGHNESS_PNG_SCALE_M {
                let k = scale_m / ROUGHNESS_PNG_SCALE_M;
                m.as_mut_slice().iter_mut().for_each(|v| *v *= k);
            }
            Ok(Roughness::Metres(m))
        }
        MapFormat::Color => {
            let img = png()?.to_rgb8();
            check(img.dimensions())?;
            Ok(Roughness::Colour(img))
        }
        // `.npy` never comes back: the wire carries it as F32.
        MapFormat::F32 | MapFormat::Npy => {
            if bytes.len() != 4 * w * h {
                return Err(MapProblem::Float32Bytes {
                    bytes: bytes.len(),
                    width: w,
                    height: h,
                });
            }
            let data = bytes
                .chunks_exact(4)
                .map(|b| f64::from(f32::from_le_bytes([b[0], b[1], b[2], b[3]])))
                .collect();
            Grid::from_vec(w, h, data)
                .map(Roughness::Metres)
                .map_err(MapProblem::Grid)
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn wire(format: pb::Format, roughness: Vec<u8>, (w, h): (u32, u32)) -> WireResult {
        WireResult(pb::Result {
            sequence: 7,
            width: w,
            height: h,
            format: format as i32,
            scale_m: ROUGHNESS_PNG_SCALE_M,
            roughness,
            latency_ms: 12.5,
            ..Default::default()
        })
    }

    #[test]
    fn png16_and_f32_decode_to_the_same_metres_with_holes() {
        let truth = Grid::from_vec(3, 2, vec![0.0, 0.0123, f64::NAN, 6.5535, 0.5, 1e-4]).unwrap();
        let mut png = Vec::new();
        io::encode_png(
            &DynamicImage::ImageLumaA16(io::roughness_png16(&truth)),
            &mut png,
        )
        .unwrap();
        let f32s: Vec<u8> = truth
            .as_slice()
            .iter()
            .flat_map(|&v| (v as f32).to_le_bytes())
            .collect();
        for (format, bytes) in [(pb::Format::Png16, png), (pb::Format::F32, f32s)] {
            let r = FrameResult::try_from((wire(format, bytes, (3, 2)), Stamp::now())).unwrap();
            let m = r.roughness_m().unwrap();
            for (got, want) in m.as_slice().iter().zip(truth.as_slice()) {
                assert!(
                    (got.is_nan() && want.is_nan()) || (got - want).abs() < 1e-6,
                    "{format:?}: {got} vs {want}"
                );
            }
            assert_eq!(r.server_latency, Duration::from_micros(12_500));
        }
    }

    #[test]
    fn a_map_of_the_wrong_size_names_the_frame() {
        let e = FrameResult::try_from((wire(pb::Format::F32, vec![0; 8], (3, 2)), Stamp::now()))
            .unwrap_err();
        assert!(
            matches!(&e, ClientError::BadResult { sequence: 7, reason } if reason.to_string().contains("3×2")),
            "{e}"
        );
        assert_eq!(
            e.to_string(),
            "result for frame 7: roughness: 8 bytes of float32 for 3×2 pixels"
        );
        let e = FrameResult::try_from((
            wire(pb::Format::Png16, b"not a png".to_vec(), (3, 2)),
            Stamp::now(),
        ))
        .unwrap_err();
        assert!(
            matches!(
                &e,
                ClientError::BadResult {
                    sequence: 7,
                    reason: ResultProblem::Map {
                        map: "roughness",
                        reason: MapProblem::Png(_)
                    }
                }
            ),
            "{e}"
        );
    }

    #[test]
    fn three_state_and_uncertainty_bytes_decode_and_bad_ones_name_the_field() {
        let mut w = wire(pb::Format::F32, vec![0; 24], (3, 2));
        w.0.traversal = vec![0, 1, 2, 2, 1, 0];
        w.0.uncertainty = [0.01f32, f32::NAN, 0.0, 0.02, 0.5, 0.001]
            .iter()
            .flat_map(|v| v.to_le_bytes())
            .collect();
        let r = FrameResult::try_from((WireResult(w.0.clone()), Stamp::now())).unwrap();
        let t = r.traversal.unwrap();
        assert_eq!(t[(2, 0)], Traversal::Hazard);
        assert_eq!(t[(1, 0)], Traversal::Traversable);
        assert_eq!(t[(0, 0)], Traversal::Unknown);
        let u = r.uncertainty_m.unwrap();
        assert!(u[(1, 0)].is_nan() && (u[(1, 1)] - 0.5).abs() < 1e-7);
        w.0.traversal[3] = 7;
        let e = FrameResult::try_from((w, Stamp::now())).unwrap_err();
        assert!(e.to_string().contains("traversal: byte 7"), "{e}");
    }

    #[test]
    fn camera_sensor_goes_out_as_a_name_or_coefficients() {
        let mut cam: CameraFile =
            serde_json::from_str(r#"{"fx": 500, "fy": 500, "cx": 1, "cy": 1, "sensor": "lidar"}"#)
                .unwrap();
        let pb_cam = pb_camera(&cam);
        assert_eq!(pb_cam.sensor.as_deref(), Some("lidar"));
        assert!(pb_cam.sensor_sigma_mm.is_empty());
        cam.sensor = Some(io::SensorSpec::Model(SensorNoise::Coefficients {
            sigma_mm: [1.0, 0.0, 2.0],
        }));
        let pb_cam = pb_camera(&cam);
        assert_eq!(
            (pb_cam.sensor, pb_cam.sensor_sigma_mm),
            (None, vec![1.0, 0.0, 2.0])
        );
    }

    #[test]
    fn garbage_from_the_server_is_a_protocol_error() {
        assert!(matches!(
            decode_server(&[0xFF, 0xFF, 0xFF]),
            Err(ClientError::Protocol(_))
        ));
        assert!(matches!(decode_server(&[]), Err(ClientError::Protocol(_))));
    }

    #[test]
    fn hello_carries_the_settings() {
        use tre_core::kinds::{Mode, NormalsMethod};
        let cfg = ClientConfig {
            mode: Some(Mode::Rgbd),
            format: MapFormat::F32,
            seed: 42,
            normals: Some(NormalsMethod::Ls),
            dsac_hypotheses: Some(4),
            want_traversable: true,
            ..ClientConfig::default()
        };
        let m = pb::ClientMessage::decode(&hello(&cfg)[..]).unwrap();
        let Some(pb::client_message::Msg::Hello(h)) = m.msg else {
            panic!("not a hello")
        };
        assert_eq!(
            (h.mode, h.format, h.seed, h.want_traversable, h.normals),
            (
                pb::Mode::Rgbd as i32,
                pb::Format::F32 as i32,
                42,
                true,
                pb::Normals::Ls as i32
            )
        );
        assert_eq!(h.dsac_hypotheses, 4);
        let default = pb::Hello::from(&ClientConfig::default());
        assert_eq!(default.dsac_hypotheses, 0, "0 leaves the server's default");
    }
}
