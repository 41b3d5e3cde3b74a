//! A stream's grid map (docs/map.md): kept per stream when its Hello asks for one, fused by the
//! worker that ran each frame, sent as `MapUpdate` messages and served by
//! `GET /v1/streams/{id}/map`.

use std::collections::HashMap;
use std::sync::{Arc, Mutex, PoisonError, Weak};

use super::error::RequestError;
use tre_core::geometry::{Intrinsics, Vec3};
use tre_core::map::{
    GravitySource, MapError, MapParams, MapPreset, MapSession, Pose, SessionFrame, LAYER_NAMES,
    LAYER_UNITS,
};
use tre_core::roughness::noise::SensorNoise;
use tre_pipeline::{FrameInput, FrameOutput, DEFAULT_HFOV_DEG};
use tre_proto::v1 as pb;

/// What a Hello asks of the map.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MapSettings {
    /// The map's settings: the server's (`tre serve --map-params`, [`MapSettings::on`]; the
    /// indoor preset until then), with the Hello's cell side and cells along a side.
    pub params: MapParams,
    /// The Hello's cell side, metres, and cells along a side, where it gave them.
    pub asked: (Option<f64>, Option<usize>),
    /// Most updates a second (0: after every fused frame).
    pub send_hz: f64,
    /// The world's down direction in the pose frame, if given.
    pub gravity: Option<Vec3>,
}

impl MapSettings {
    /// These settings on the server's `base` settings: the Hello's cell side and cells along a
    /// side where it gave them, the rest the server's.
    #[must_use]
    pub fn on(mut self, base: &MapParams) -> Self {
        self.params = *base;
        let c = &mut self.params.config;
        (c.cell_m, c.side) = (
            self.asked.0.unwrap_or(c.cell_m),
            self.asked.1.unwrap_or(c.side),
        );
        self
    }
}

/// A stream's map and its counts.
#[derive(Debug)]
pub struct SessionMap {
    /// The settings.
    pub settings: MapSettings,
    /// The map session, from the first frame that comes with the noise model it needs.
    pub session: Option<MapSession>,
    /// The last frame fused.
    pub sequence: u64,
    /// Frames skipped before a session could start.
    pub skipped_before: u64,
}

/// Why a stream's frame was not fused.
#[derive(Debug, thiserror::Error)]
pub(crate) enum NotFused {
    /// The frame carries no sensor depth.
    #[error("the frame has no sensor depth")]
    NoDepth,
    /// Its size gives no default intrinsics.
    #[error("{0}")]
    Intrinsics(tre_core::geometry::GeometryError),
    /// The map could not take it.
    #[error("{0}")]
    Map(#[from] MapError),
}

/// A shared handle on a stream's map.
pub(crate) type SharedMap = Arc<Mutex<SessionMap>>;

/// The maps of the open streams, by stream id (entries of closed streams are dropped when
/// looked up or when a stream opens).
#[derive(Debug, Default)]
pub(crate) struct MapRegistry {
    maps: Mutex<HashMap<String, Weak<Mutex<SessionMap>>>>,
}

impl MapRegistry {
    /// Registers the map of stream `id`.
    pub(crate) fn insert(&self, id: &str, map: &SharedMap) {
        let mut maps = self.maps.lock().unwrap_or_else(PoisonError::into_inner);
        maps.retain(|_, m| m.strong_count() > 0);
        maps.insert(id.to_owned(), Arc::downgrade(map));
    }

    /// The map of stream `id`, while the stream is open.
    pub(crate) fn get(&self, id: &str) -> Option<SharedMap> {
        let maps = self.maps.lock().unwrap_or_else(PoisonError::into_inner);
        maps.get(id).and_then(Weak::upgrade)
    }
}

/// A frame's part in the map: the map and the frame's pose (`None`: the frame alone).
#[derive(Debug, Clone)]
pub struct MapJob {
    /// The stream's map.
    pub map: SharedMap,
    /// The camera-to-world pose.
    pub pose: Option<Pose>,
    /// The frame's sequence number.
    pub sequence: u64,
}

impl SessionMap {
    /// An empty map with these settings.
    pub fn new(settings: MapSettings) -> Self {
        Self {
            settings,
            session: None,
            sequence: 0,
            skipped_before: 0,
        }
    }

    /// Fuses one answered frame (on the worker that ran it): its sensor depth and the pose
    /// (without one the map restarts on the frame, centred on the camera), gravity from the
    /// Hello's or from the frames' ground. A frame that cannot be fused is counted skipped,
    /// logged, and the map keeps what it had.
    pub fn fuse(
        &mut self,
        frame: &FrameInput,
        out: &FrameOutput,
        job: &MapJob,
        sensor: &SensorNoise,
    ) {
        match self.try_fuse(frame, out, job, sensor) {
            Ok(()) => self.sequence = job.sequence,
            Err(why) => {
                if !matches!(why, NotFused::Map(_)) {
                    self.skipped_before += 1;
                }
                tracing::info!(sequence = job.sequence, "map: frame skipped: {why}");
            }
        }
    }

    fn try_fuse(
        &mut self,
        frame: &FrameInput,
        out: &FrameOutput,
        job: &MapJob,
        sensor: &SensorNoise,
    ) -> Result<(), NotFused> {
        let depth = frame.depth_m.as_ref().ok_or(NotFused::NoDepth)?;
        let (w, h) = depth.size();
        let k = match frame.intrinsics {
            Some(k) => k,
            None => Intrinsics::from_hfov(w, h, DEFAULT_HFOV_DEG).map_err(NotFused::Intrinsics)?,
        };
        let points = k.back_project_map(depth);
        let settings = self.settings;
        let session = self.session.get_or_insert_with(|| {
            let gravity = settings
                .gravity
                .map_or(GravitySource::Ground, GravitySource::Given);
            MapSession::new(settings.params, gravity, *sensor)
        });
        session.fuse(&SessionFrame {
            points: &points,
            pose: job.pose,
            t_s: job.sequence as f64,
            ground_up_in_cam: out.gravity.up_in_cam(),
        })?;
        Ok(())
    }

    /// Frames fused and skipped.
    pub fn counts(&self) -> (u64, u64) {
        let (fused, skipped) = self
            .session
            .as_ref()
            .map_or((0, 0), |s| (s.fused(), s.skipped().0));
        (fused, skipped + self.skipped_before)
    }

    /// The map as a `MapUpdate` message, once a frame started it.
    pub fn update(&self) -> Option<pb::MapUpdate> {
        let session = self.session.as_ref()?;
        let map = session.map()?;
        let layers = session.layers()?;
        let (fused, skipped) = self.counts();
        let cfg = map.config();
        let r = map.frame().map_from_world;
        Some(pb::MapUpdate {
            sequence: self.sequence,
            cell_m: cfg.cell_m,
            side: cfg.side as u32,
            origin_x: map.origin().0,
            origin_y: map.origin().1,
            map_from_world: (0..3)
                .flat_map(|i| (0..3).map(move |j| r[(i, j)]))
                .collect(),
            layers: LAYER_NAMES
                .iter()
                .zip(LAYER_UNITS)
                .zip(layers.all())
                .map(|((name, unit), grid)| pb::MapLayer {
                    name: (*name).to_owned(),
                    unit: unit.to_owned(),
                    data: grid
                        .as_slice()
                        .iter()
                        .flat_map(|v| v.to_le_bytes())
                        .collect(),
                })
                .collect(),
            fused,
            skipped,
        })
    }
}

/// The map settings of a Hello's `map`, checked: a cell of 1 mm to 1 m, 1 to 1,000 cells a
/// side, a finite non-negative rate, gravity of 3 finite values if given.
pub(crate) fn settings_from_pb(m: &pb::MapSettings) -> Result<MapSettings, RequestError> {
    let indoor = MapParams::preset(MapPreset::Indoor);
    let asked = (
        (m.cell_m != 0.0).then_some(m.cell_m),
        (m.side != 0).then_some(m.side as usize),
    );
    let cell_m = asked.0.unwrap_or(indoor.config.cell_m);
    let side = asked.1.unwrap_or(indoor.config.side);
    if !(cell_m.is_finite() && (0.001..=1.0).contains(&cell_m)) {
        return Err(RequestError::MapCellSize { cell_m });
    }
    if side > 1000 {
        return Err(RequestError::MapSide { side });
    }
    if !(m.send_hz.is_finite() && m.send_hz >= 0.0) {
        return Err(RequestError::MapSendRate { send_hz: m.send_hz });
    }
    let gravity = match m.gravity.as_slice() {
        [] => None,
        &[x, y, z] if [x, y, z].iter().all(|v| v.is_finite()) && (x, y, z) != (0.0, 0.0, 0.0) => {
            Some(Vec3::new(x, y, z))
        }
        other => {
            return Err(RequestError::MapGravity {
                gravity: other.to_vec(),
            })
        }
    };
    Ok(MapSettings {
        params: indoor,
        asked,
        send_hz: m.send_hz,
        gravity,
    })
}
