//! One frame from the topics through the pipeline and into the map: what the node does
//! between receiving and publishing, without DDS (so it is tested and measured alone).

use tre_core::geometry::{Intrinsics, PointMap, Vec3};
use tre_core::map::{
    GravitySource, GridMap as Map, Layers, MapError, MapParams, MapSession, Pose as MapPose,
    SessionFrame,
};
use tre_core::roughness::noise::SensorNoise;
use tre_pipeline::{FrameInput, Pipeline, PipelineConfig, PipelineError};
use tre_record::encode;
use tre_record::msgs::{CameraInfo, CompressedImage, GridMap, Header, Image, OccupancyGrid};

use crate::convert;
use crate::error::InputError;

/// The messages of one frame.
#[derive(Debug, Clone)]
pub struct FrameMsgs {
    /// Depth (`geometric`, `rgbd`).
    pub depth: Option<Image>,
    /// Colour (`rgb`, `rgbd`).
    pub colour: Option<Image>,
    /// The latest camera_info, if any has arrived.
    pub info: Option<CameraInfo>,
    /// The camera's pose at the frame's stamp (camera to the map's world), when a pose source
    /// is configured and had one.
    pub pose: Option<MapPose>,
}

impl FrameMsgs {
    /// The header the outputs carry: the depth frame's, else the colour frame's.
    pub fn header(&self) -> Header {
        self.depth
            .as_ref()
            .or(self.colour.as_ref())
            .map(|i| i.header.clone())
            .unwrap_or_default()
    }
}

/// What one frame gave.
#[derive(Debug, Clone)]
pub struct Outputs {
    /// Roughness, `32FC1` metres (NaN: no data) or `mono16` millimetres (0: no data), stamped
    /// with the input's header.
    pub roughness: Image,
    /// The uncertainty, metres, `32FC1`, when asked for and the mode has a noise model or a
    /// calibration.
    pub uncertainty: Option<Image>,
    /// Three-state traversability, `mono8` (0 unknown, 1 traversable, 2 hazard), when asked
    /// for.
    pub traversal: Option<Image>,
    /// The images above as PNGs (`{topic}/compressed`), when asked for: the roughness, the
    /// uncertainty and the three-state image, in that order, each when its image is there.
    pub compressed: Vec<(&'static str, CompressedImage)>,
    /// The fused map after this frame, when a pose came with it and its period is due.
    pub grid: Option<GridMap>,
    /// The map's three-state layer for Nav2.
    pub occupancy: Option<OccupancyGrid>,
    /// The map's layers after this frame.
    pub layers: Option<Layers>,
    /// Why the frame was not fused into the map (the map keeps what it had).
    pub map_error: Option<MapError>,
}

impl Outputs {
    /// The PNGs of the roughness, the uncertainty and the three-state image (those there).
    fn pngs(&self) -> Vec<(&'static str, CompressedImage)> {
        let images = [
            ("roughness", Some(&self.roughness)),
            ("uncertainty", self.uncertainty.as_ref()),
            ("traversal", self.traversal.as_ref()),
        ];
        images
            .into_iter()
            .filter_map(|(name, img)| Some((name, crate::compressed::png(img?)?)))
            .collect()
    }
}

/// How the roughness image is encoded.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum RoughnessEncoding {
    /// `32FC1`, metres, NaN where there is no data: the pipeline's values bit for bit
    /// (4 bytes a pixel).
    #[default]
    Float32,
    /// `mono16`, millimetres rounded to the nearest, 0 where there is no data (a roughness
    /// under 0.5 mm is written as 1, one over 65.535 m as 65535): half the bytes.
    Mono16Mm,
}

/// The per-frame images published beside the roughness.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct ImageOutputs {
    /// The uncertainty image (`32FC1`, metres; needs a sensor model).
    pub uncertainty: bool,
    /// The three-state image (`mono8`; needs a sensor model).
    pub traversal: bool,
    /// The roughness image's encoding.
    pub roughness: RoughnessEncoding,
    /// Each image also as a PNG `sensor_msgs/CompressedImage` on `{topic}/compressed`.
    pub compressed: bool,
}

impl Default for ImageOutputs {
    /// The roughness alone, `32FC1`, and its PNG.
    fn default() -> Self {
        Self {
            uncertainty: false,
            traversal: false,
            roughness: RoughnessEncoding::Float32,
            compressed: true,
        }
    }
}

impl ImageOutputs {
    /// Every image, the roughness as `32FC1`, and their PNGs.
    pub fn all() -> Self {
        Self {
            uncertainty: true,
            traversal: true,
            ..Self::default()
        }
    }

    /// Whether the sensor maps (uncertainty and three-state) are needed.
    fn sensor_maps(&self) -> bool {
        self.uncertainty || self.traversal
    }
}

/// The fused map's settings.
#[derive(Debug, Clone)]
pub struct MapSettings {
    /// The grid, the fusion and the thresholds of its three-state layer.
    pub params: MapParams,
    /// Gravity (down) in the pose's world frame (ROS: −z, REP 103).
    pub down: Vec3,
    /// `frame_id` of the published map (the frame of the poses, levelled by `down`).
    pub frame_id: String,
    /// The layers the grid_map message carries (of `tre_core::map::LAYER_NAMES`; 160 KB a
    /// layer for the default 200×200 cells).
    pub grid_layers: Vec<&'static str>,
    /// The grid_map message at most once this period (by the frames' stamps; zero: every
    /// fused frame); the occupancy grid goes out with every fused frame.
    pub grid_period: std::time::Duration,
}

/// The map and where it started.
#[derive(Debug)]
struct MapState {
    settings: MapSettings,
    session: Option<MapSession>,
    /// Stamp of the first fused frame, nanoseconds: the map's times count from it.
    t0_ns: Option<i64>,
    /// Stamp of the frame whose grid_map was last published, nanoseconds.
    last_grid_ns: Option<i64>,
}

/// The pipeline's input of a frame's messages, and its intrinsics.
fn frame_input(f: &FrameMsgs) -> Result<(FrameInput, Intrinsics), InputError> {
    let image = f
        .depth
        .as_ref()
        .or(f.colour.as_ref())
        .ok_or(InputError::Empty)?;
    // The images first: what is wrong with a frame itself is said whatever camera_info came.
    let depth_m = f.depth.as_ref().map(convert::depth_m).transpose()?;
    let rgb = f.colour.as_ref().map(convert::rgb).transpose()?;
    if let (Some(c), Some(d)) = (&f.colour, &f.depth) {
        if (c.width, c.height) != (d.width, d.height) {
            return Err(InputError::SizeMismatch {
                info: (d.width, d.height),
                image: (c.width, c.height),
            });
        }
    }
    let info = f.info.as_ref().ok_or(InputError::NoCameraInfo)?;
    let k = convert::intrinsics(info, image)?;
    let input = FrameInput {
        rgb,
        depth_m,
        intrinsics: Some(k),
        mounting: None,
        sensor: None,
    };
    Ok((input, k))
}

impl MapState {
    /// Fuses a frame's points at `pose` (the map starts at its first frame, levelled by the
    /// settings' gravity); the map's messages and layers after it.
    fn fuse(
        &mut self,
        points: &PointMap,
        pose: &MapPose,
        header: &Header,
        sensor: &SensorNoise,
    ) -> Result<(Option<GridMap>, OccupancyGrid, Layers), MapError> {
        let t_ns = header.stamp.nanos();
        let t0 = *self.t0_ns.get_or_insert(t_ns);
        let t_s = (t_ns - t0) as f64 * 1e-9;
        let settings = &self.settings;
        let session = self.session.get_or_insert_with(|| {
            MapSession::new(
                settings.params,
                GravitySource::Given(settings.down),
                *sensor,
            )
        });
        session.fuse(&SessionFrame {
            points,
            pose: Some(*pose),
            t_s,
            ground_up_in_cam: None,
        })?;
        let (Some(m), Some(layers)) = (session.map(), session.layers()) else {
            return Err(MapError::NothingSeen);
        };
        let h = Header {
            stamp: header.stamp,
            frame_id: self.settings.frame_id.clone(),
        };
        // The grid_map message (160 KB a layer) at most once a grid period, by the frames'
        // stamps; the occupancy grid (a byte a cell) every frame.
        let period = i64::try_from(self.settings.grid_period.as_nanos()).unwrap_or(i64::MAX);
        let due = self
            .last_grid_ns
            .is_none_or(|last| t_ns < last || t_ns - last >= period);
        let grid = due.then(|| {
            self.last_grid_ns = Some(t_ns);
            encode::grid_map_layers(&h, m, &layers, &self.settings.grid_layers)
        });
        Ok((grid, encode::occupancy(&h, m, &layers), layers))
    }
}

/// The pipeline, its configuration, the sensor's noise model and the map.
#[derive(Debug)]
pub struct Processor {
    pipeline: Pipeline,
    cfg: PipelineConfig,
    sensor: Option<SensorNoise>,
    map: Option<MapState>,
    images: ImageOutputs,
    /// A camera_info listing lens distortion was warned of (once a node).
    distortion_said: bool,
    /// Remap each raw image into its camera_info's pinhole (`--undistort`); the remapping of
    /// the last camera_info.
    undistort: bool,
    rectifier: Option<crate::rectify::Rectifier>,
}

impl Processor {
    /// A processor running `cfg` on `pipeline`; `sensor` gives the uncertainty and three-state
    /// maps (and the map's height variance); `map` fuses frames that come with a pose.
    pub fn new(
        pipeline: Pipeline,
        cfg: PipelineConfig,
        sensor: Option<SensorNoise>,
        map: Option<MapSettings>,
    ) -> Self {
        Self {
            pipeline,
            cfg,
            sensor,
            map: map.map(|settings| MapState {
                settings,
                session: None,
                t0_ns: None,
                last_grid_ns: None,
            }),
            images: ImageOutputs::default(),
            distortion_said: false,
            undistort: false,
            rectifier: None,
        }
    }

    /// The same processor remapping each image, a raw and distorted one, into its
    /// camera_info's pinhole before the pipeline (`--undistort`, [`crate::rectify`]).
    pub fn with_undistort(mut self, undistort: bool) -> Self {
        self.undistort = undistort;
        self
    }

    /// The images published beside the roughness, and its encoding (default: the roughness
    /// alone, `32FC1`).
    pub fn with_images(mut self, images: ImageOutputs) -> Self {
        self.images = images;
        self
    }

    /// The images it publishes.
    pub fn images(&self) -> ImageOutputs {
        self.images
    }

    /// The pipeline's configuration.
    pub fn config(&self) -> &PipelineConfig {
        &self.cfg
    }

    /// Warns, once a node, of a camera_info that lists lens distortion: the image is read as
    /// rectified all the same ([`convert::intrinsics`]).
    fn say_distortion(&mut self, info: Option<&CameraInfo>) {
        let Some(info) = info.filter(|i| convert::lists_distortion(i)) else {
            return;
        };
        if !self.distortion_said {
            self.distortion_said = true;
            tracing::warn!(
                model = info.distortion_model,
                "camera_info lists lens distortion: the depth is read as a rectified image, \
                 through camera_info's p (as depth_image_proc reads depth); subscribe to the \
                 rectified depth (image_rect), or pass --undistort for a raw one"
            );
        }
    }

    /// The frame's intrinsics: with `--undistort` its images remapped into `info`'s pinhole;
    /// else `k` as read, with the warning of a listed distortion.
    fn camera(
        &mut self,
        info: Option<&CameraInfo>,
        input: &mut FrameInput,
        k: Intrinsics,
    ) -> Result<Intrinsics, InputError> {
        match info {
            Some(info) if self.undistort => self.rectify(info, input),
            _ => {
                self.say_distortion(info);
                Ok(k)
            }
        }
    }

    /// Remaps the frame's images into `info`'s pinhole (the remapping made again when the
    /// calibration changes); the rectified intrinsics.
    fn rectify(
        &mut self,
        info: &CameraInfo,
        input: &mut FrameInput,
    ) -> Result<Intrinsics, InputError> {
        let r = match self.rectifier.take() {
            Some(r) if r.fits(info) => r,
            _ => crate::rectify::Rectifier::new(info)?,
        };
        input.depth_m = input.depth_m.as_ref().map(|d| r.depth(d));
        input.rgb = input.rgb.as_ref().map(|c| r.rgb(c));
        let k = r.intrinsics();
        input.intrinsics = Some(k);
        self.rectifier = Some(r);
        Ok(k)
    }

    /// The frame's outputs, or why it was skipped.
    pub fn process(&mut self, f: &FrameMsgs) -> Result<Outputs, InputError> {
        let header = f.header();
        let (mut input, k) = frame_input(f)?;
        let k = self.camera(f.info.as_ref(), &mut input, k)?;
        input.sensor = self.sensor;
        tre_pipeline::check_input(&input, &self.cfg).map_err(InputError::Pipeline)?;
        let out = self
            .pipeline
            .run(&input, &self.cfg)
            .map_err(InputError::Pipeline)?;
        let roughness = match self.images.roughness {
            RoughnessEncoding::Float32 => encode::float_image(&header, &out.roughness_m),
            RoughnessEncoding::Mono16Mm => encode::mono16_mm_image(&header, &out.roughness_m),
        };
        let maps = if self.images.sensor_maps() {
            let table = self.pipeline.interval_table_for(&self.cfg);
            match out.sensor_maps(&input, self.cfg.mode, self.sensor.as_ref(), None, table) {
                Ok(maps) => Some(maps),
                Err(PipelineError::NoSensorModel { .. } | PipelineError::NoSensorDepth { .. }) => {
                    None
                }
                Err(e) => return Err(InputError::Pipeline(e)),
            }
        } else {
            None
        };
        let maps = maps.as_ref();
        let mut outputs = Outputs {
            roughness,
            uncertainty: maps
                .filter(|_| self.images.uncertainty)
                .map(|m| encode::float_image(&header, &m.uncertainty_m)),
            traversal: maps
                .filter(|_| self.images.traversal)
                .map(|m| encode::traversal_image(&header, &m.traversal)),
            compressed: Vec::new(),
            grid: None,
            occupancy: None,
            layers: None,
            map_error: None,
        };
        if self.images.compressed {
            outputs.compressed = outputs.pngs();
        }
        if let (Some(state), Some(pose), Some(depth), Some(sensor)) =
            (&mut self.map, f.pose, &input.depth_m, self.sensor)
        {
            let points = k.back_project_map(depth);
            let fused = state.fuse(&points, &pose, &header, &sensor);
            match fused {
                Ok((grid, occupancy, layers)) => {
                    outputs.grid = grid;
                    outputs.occupancy = Some(occupancy);
                    outputs.layers = Some(layers);
                }
                Err(e) => outputs.map_error = Some(e),
            }
        }
        self.pipeline.recycle(out);
        Ok(outputs)
    }

    /// The fused map, if one has started.
    pub fn map(&self) -> Option<&Map> {
        self.map
            .as_ref()
            .and_then(|s| s.session.as_ref())
            .and_then(MapSession::map)
    }

    /// The map's settings, if it is on.
    pub fn map_settings(&self) -> Option<&MapSettings> {
        self.map.as_ref().map(|s| &s.settings)
    }
}
