//! What a client asks for, in domain types (HTTP and stream requests both become a
//! [`FrameRequest`]), and the worker-side steps around the pipeline: decoding the bytes under
//! the limits, choosing the configuration, and encoding the maps for the answer.

use std::io::Cursor;

use image::{DynamicImage, ImageFormat, ImageReader};

pub use super::error::ImagePart;
use super::error::RequestError;
use super::options::{FrameOptions, OutputMap};
use tre_core::geometry::Grid;
use tre_core::kinds::MapFormat;
use tre_core::roughness::interval::IntervalTable;
use tre_io::{self as io, colormap, CameraFile, ROUGHNESS_PNG_SCALE_M};
use tre_pipeline::{
    Assumption, FrameInput, FrameOutput, Gravity, Mode, NormalsMethod, PipelineConfig,
    PipelineError, DEFAULT_DSAC_HYPOTHESES,
};

/// A frame as received: encoded images and an unchecked camera.
#[derive(Debug, Clone, Default)]
pub struct FrameRequest {
    /// PNG or JPEG bytes.
    pub rgb: Option<Vec<u8>>,
    /// 16-bit grey PNG or float `.npy` bytes.
    pub depth: Option<Vec<u8>>,
    /// Intrinsics, mounting and depth scale.
    pub camera: Option<CameraFile>,
    /// What to run and return.
    pub options: FrameOptions,
    /// The stream's map this frame is fused into, if it keeps one.
    pub map: Option<super::map::MapJob>,
}

impl FrameRequest {
    /// The depth sensor's noise model: the options' `sensor`, else the camera's.
    pub fn noise_model(&self) -> Option<tre_core::roughness::noise::SensorNoise> {
        let camera = self.camera.as_ref().and_then(|c| c.sensor.as_ref());
        self.options
            .sensor
            .or_else(|| camera.and_then(io::SensorSpec::noise))
    }
}

/// Decoding limits, all checked from the header before any pixel is decoded.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct DecodeLimits {
    /// Largest image, pixels.
    pub max_pixels: usize,
    /// Longest side, pixels.
    pub max_side: usize,
    /// Largest ratio of the longer side to the shorter one.
    pub max_aspect: usize,
}

impl Default for DecodeLimits {
    fn default() -> Self {
        Self {
            max_pixels: 4 << 20,
            max_side: 8192,
            max_aspect: 8,
        }
    }
}

impl DecodeLimits {
    /// Checks a `w`×`h` image `part` against the limits: 422 `bad_image` (`bad_depth` for
    /// depth) without pixels or beyond the aspect ratio, 413 `too_large` beyond the side or the
    /// pixel count; each message names the limit and its option.
    pub fn check_shape(&self, part: ImagePart, w: usize, h: usize) -> Result<(), RequestError> {
        let (long, short) = (w.max(h), w.min(h));
        let size = (w, h);
        let pixels = (w as u64).saturating_mul(h as u64);
        if short == 0 {
            return Err(RequestError::NoPixels { part, size });
        }
        if long > self.max_side {
            let max_side = self.max_side;
            return Err(RequestError::SideTooLong {
                part,
                size,
                max_side,
            });
        }
        if pixels > self.max_pixels as u64 {
            let max_pixels = self.max_pixels;
            return Err(RequestError::TooManyPixels {
                part,
                size,
                max_pixels,
            });
        }
        if long > short.saturating_mul(self.max_aspect) {
            let max_aspect = self.max_aspect;
            return Err(RequestError::TooNarrow {
                part,
                size,
                max_aspect,
            });
        }
        Ok(())
    }
}

/// One extra output map, encoded.
#[derive(Debug, Clone)]
pub struct Part {
    /// `depth`, `normals`, `slope`, `traversable` or `boundary`.
    pub name: &'static str,
    /// Its MIME type.
    pub content_type: &'static str,
    /// Its file name (for multipart answers).
    pub filename: &'static str,
    /// The bytes.
    pub bytes: Vec<u8>,
}

/// The answer to one frame.
#[derive(Debug, Clone)]
pub struct FrameReply {
    /// `(width, height)` of the frame and the maps.
    pub size: (usize, usize),
    /// Size the stages ran at.
    pub working_size: (usize, usize),
    /// The roughness map, encoded.
    pub roughness: Vec<u8>,
    /// How it is encoded.
    pub format: MapFormat,
    /// Extra maps, encoded.
    pub extras: Vec<Part>,
    /// Traversability, one byte per pixel (1 = traversable), if asked for as bytes.
    pub traversable: Vec<u8>,
    /// Three-state traversability, one byte per pixel, if asked for as bytes.
    pub traversal: Vec<u8>,
    /// Uncertainty, little-endian float32 metres, if asked for as bytes.
    pub uncertainty: Vec<u8>,
    /// Wall time of each stage.
    pub timings: tre_pipeline::StageTimings,
    /// The mode that ran.
    pub mode: Mode,
    /// What stood in for what the request did not give.
    pub assumed: Vec<Assumption>,
    /// Where gravity came from.
    pub gravity: Gravity,
    /// What looks wrong with the input (an implausibly scaled depth), in words.
    pub warnings: Vec<String>,
}

/// PNG and JPEG magic numbers.
fn sniff(bytes: &[u8]) -> Option<ImageFormat> {
    if bytes.starts_with(b"\x89PNG\r\n\x1a\n") {
        Some(ImageFormat::Png)
    } else if bytes.starts_with(&[0xFF, 0xD8, 0xFF]) {
        Some(ImageFormat::Jpeg)
    } else {
        None
    }
}

/// Decodes image `part` after checking its header against the pixel limit, so a small file
/// that declares a huge image is refused before any allocation.
pub fn decode_image(
    part: ImagePart,
    bytes: &[u8],
    limits: DecodeLimits,
) -> Result<DynamicImage, RequestError> {
    let (format, (w, h)) = image_header(part, bytes, limits)?;
    let pixels = u64::from(w) * u64::from(h);
    if format == ImageFormat::Jpeg {
        return io::decode_jpeg(bytes).map_err(|source| RequestError::Jpeg { part, source });
    }
    let mut reader = ImageReader::with_format(Cursor::new(bytes), format);
    let mut l = image::Limits::default();
    l.max_image_width = Some(w);
    l.max_image_height = Some(h);
    l.max_alloc = Some(pixels * 16 + (1 << 20));
    reader.limits(l);
    reader
        .decode()
        .map_err(|source| RequestError::Undecodable { part, source })
}

/// The format and size of image `part` from its header, checked against the limits, without
/// decoding its pixels.
pub fn image_header(
    part: ImagePart,
    bytes: &[u8],
    limits: DecodeLimits,
) -> Result<(ImageFormat, (u32, u32)), RequestError> {
    if bytes.is_empty() {
        return Err(RequestError::EmptyImage { part });
    }
    let Some(format) = sniff(bytes) else {
        return Err(RequestError::NotAnImage { part });
    };
    let (w, h) = ImageReader::with_format(Cursor::new(bytes), format)
        .into_dimensions()
        .map_err(|source| RequestError::Undecodable { part, source })?;
    limits.check_shape(part, w as usize, h as usize)?;
    Ok((format, (w, h)))
}

/// Keys a camera JSON sent over HTTP or the stream may carry, those a camera file is read for;
/// any other is refused there (files read by the CLI keep their notes, such as `source` or
/// `licence`).
pub use tre_io::CAMERA_KEYS;

/// Physical ranges of a camera sent by a client: focal lengths 1 px to 10⁶ px, pitch −90° to
/// 90°, height above the ground 1 cm to 100 m, depth scale above 0 and at most 10⁶ units per
/// metre, a stated size within the side limit. Anything else is 422 `bad_camera`.
pub fn check_camera_ranges(cam: &CameraFile, limits: DecodeLimits) -> Result<(), RequestError> {
    let within = |name, v: Option<f64>, lo, hi, unit| match v {
        Some(value) if !(value.is_finite() && (lo..=hi).contains(&value)) => {
            Err(RequestError::CameraRange {
                name,
                value,
                lo,
                hi,
                unit,
            })
        }
        _ => Ok(()),
    };
    within("fx", Some(cam.fx), 1.0, 1e6, "px")?;
    within("fy", Some(cam.fy), 1.0, 1e6, "px")?;
    within("cx", Some(cam.cx), -1e6, 1e6, "px")?;
    within("cy", Some(cam.cy), -1e6, 1e6, "px")?;
    within("pitch_deg", cam.pitch_deg, -90.0, 90.0, "degrees")?;
    within("height_m", cam.height_m, 0.01, 100.0, "m")?;
    within("depth_scale", cam.depth_scale, 1e-3, 1e6, "units per metre")?;
    for (name, side) in [("width", cam.width), ("height", cam.height)] {
        if let Some(side) = side.filter(|&s| s == 0 || s > limits.max_side) {
            return Err(RequestError::CameraSide {
                name,
                side,
                max_side: limits.max_side,
            });
        }
    }
    Ok(())
}

/// A camera JSON from a client, read as every interface reads a camera file
/// ([`CameraFile`]: the parameters of [`CAMERA_KEYS`], other keys metadata unless they look
/// like a misspelt parameter), within [`check_camera_ranges`].
pub fn strict_camera(json: &[u8], limits: DecodeLimits) -> Result<CameraFile, RequestError> {
    let value: serde_json::Value =
        serde_json::from_slice(json).map_err(RequestError::CameraNotJson)?;
    if !value.is_object() {
        return Err(RequestError::CameraNotObject);
    }
    let cam: CameraFile = serde_json::from_value(value).map_err(RequestError::CameraFields)?;
    check_camera_ranges(&cam, limits)?;
    Ok(cam)
}

/// Decodes depth in metres: a 16-bit grey PNG at `units_per_m`, or a float `.npy`; depth that
/// cannot be one ([`io::check_depth`]: no valid pixel, or a median in millimetres) is refused.
pub fn decode_depth(
    bytes: &[u8],
    units_per_m: f64,
    limits: DecodeLimits,
) -> Result<Grid<f64>, RequestError> {
    let depth = depth_of(bytes, units_per_m, limits)?;
    io::check_depth(&depth)?;
    Ok(depth)
}

/// [`decode_depth`] without the check of its values.
fn depth_of(
    bytes: &[u8],
    units_per_m: f64,
    limits: DecodeLimits,
) -> Result<Grid<f64>, RequestError> {
    if bytes.starts_with(b"\x93NUMPY") {
        // The shape is bounded from the header, before any value is converted; the pixel limit
        // is then checked with the side and aspect limits, naming each.
        let array = io::npy::read_npy_within(Cursor::new(bytes), limits.max_pixels)?;
        let grid = io::npy_depth(array)?;
        let (w, h) = grid.size();
        limits.check_shape(ImagePart::Depth, w, h)?;
        return Ok(grid);
    }
    // Not an image, or a broken one: a depth error, saying what depth may be.
    let image = decode_image(ImagePart::Depth, bytes, limits).map_err(|e| match e {
        RequestError::EmptyImage { .. }
        | RequestError::NotAnImage { .. }
        | RequestError::Undecodable { .. }
        | RequestError::Jpeg { .. } => RequestError::NotDepth(Box::new(e)),
        _ => e,
    })?;
    match image {
        DynamicImage::ImageLuma16(img) => Ok(io::depth_from_luma16(img, units_per_m)),
        other => Err(RequestError::DepthColour {
            color: other.color(),
        }),
    }
}

/// An RGB frame from `bytes`, refusing 16-bit grey (depth sent as colour) with 422
/// `bad_image` that says where depth goes.
fn rgb_frame(bytes: &[u8], limits: DecodeLimits) -> Result<image::RgbImage, RequestError> {
    let image = decode_image(ImagePart::Rgb, bytes, limits)?;
    if let Some(why) = io::not_rgb(image.color()) {
        return Err(RequestError::DepthAsRgb { why });
    }
    Ok(image.to_rgb8())
}

/// The pipeline input for `req`: decoded images, checked camera.
pub fn decode_frame(req: &FrameRequest, limits: DecodeLimits) -> Result<FrameInput, RequestError> {
    let (intrinsics, mounting, scale) = match &req.camera {
        Some(c) => (
            Some(c.intrinsics().map_err(RequestError::Camera)?),
            c.mounting().map_err(RequestError::Camera)?,
            c.depth_scale.unwrap_or(1000.0),
        ),
        None => (None, None, 1000.0),
    };
    if !(scale.is_finite() && scale > 0.0) {
        return Err(RequestError::DepthScale { scale });
    }
    // `mode=rgb` predicts its own depth: a depth part would be dropped, so it is refused.
    if let Some(mode) = req.options.mode {
        PipelineConfig::for_mode(mode).check_depth_used(req.depth.is_some())?;
    }
    // The geometric mode uses no RGB: an image sent along is checked from its header (format,
    // limits, the depth's size) but not decoded.
    let geometric = req.options.mode == Some(Mode::Geometric) && req.depth.is_some();
    let (rgb, unused_rgb) = match &req.rgb {
        Some(b) if geometric => (None, Some(image_header(ImagePart::Rgb, b, limits)?.1)),
        Some(b) => (Some(rgb_frame(b, limits)?), None),
        None => (None, None),
    };
    let depth_m = match &req.depth {
        Some(b) => Some(decode_depth(b, scale, limits)?),
        None => None,
    };
    if let (Some((w, h)), Some(d)) = (unused_rgb, &depth_m) {
        let rgb = (w as usize, h as usize);
        if rgb != d.size() {
            return Err(PipelineError::DepthSizeMismatch {
                rgb,
                depth: d.size(),
            }
            .into());
        }
    }
    let frame = FrameInput {
        rgb,
        depth_m,
        intrinsics,
        mounting,
        sensor: req.noise_model(),
    };
    let Some(size) = frame.size() else {
        return Err(RequestError::NoInput);
    };
    if let Some(c) = &req.camera {
        c.check_size(size)?;
    }
    Ok(frame)
}

/// What a frame gets for the settings it does not choose itself (`tre serve --normals`,
/// `--dsac-hypotheses`).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "cli", derive(clap::Args))]
pub struct FrameDefaults {
    /// Initial normals of frames that do not choose: dsac (the paper's method) or ls (faster;
    /// see docs/evaluation.md and docs/benchmarks.md). Requests override it with `normals=`.
    #[cfg_attr(
        feature = "cli",
        arg(long, env = "TRE_NORMALS", value_enum, default_value = "dsac")
    )]
    pub normals: NormalsMethod,
    /// DSAC hypotheses per pixel, 1 to 64: 12 as the neighbour net was trained; fewer are
    /// faster at some cost in accuracy (see docs/evaluation.md).
    #[cfg_attr(feature = "cli", arg(long, env = "TRE_DSAC_HYPOTHESES",
        default_value_t = DEFAULT_DSAC_HYPOTHESES,
        value_parser = tre_core::kinds::dsac_hypotheses_parser()))]
    pub dsac_hypotheses: u32,
}

impl Default for FrameDefaults {
    /// The paper's method as trained: DSAC with [`DEFAULT_DSAC_HYPOTHESES`] hypotheses.
    fn default() -> Self {
        Self {
            normals: NormalsMethod::Dsac,
            dsac_hypotheses: DEFAULT_DSAC_HYPOTHESES,
        }
    }
}

/// The pipeline configuration for a frame with these inputs (`defaults`: the server's settings
/// for what the frame does not choose).
pub fn config_for(
    frame: &FrameInput,
    opts: &FrameOptions,
    max_pixels: usize,
    defaults: FrameDefaults,
) -> PipelineConfig {
    let mode = opts
        .mode
        .unwrap_or_else(|| Mode::implied(frame.rgb.is_some(), frame.depth_m.is_some()));
    PipelineConfig {
        seed: opts.seed,
        normals: opts.normals.unwrap_or(defaults.normals),
        dsac_hypotheses: opts.dsac_hypotheses.unwrap_or(defaults.dsac_hypotheses),
        max_input_pixels: max_pixels,
        traversability: opts.traversability,
        ..PipelineConfig::for_mode(mode)
    }
}

/// Encodes a PNG with the settings `tre infer` uses (fast compression, adaptive filter).
fn png(img: &DynamicImage) -> Result<Vec<u8>, RequestError> {
    let mut out = Vec::new();
    io::encode_png(img, &mut out).map_err(RequestError::EncodePng)?;
    Ok(out)
}

/// Writes an `.npy` into memory.
fn npy<T: io::npy::NpyElement>(shape: &[usize], data: &[T]) -> Result<Vec<u8>, RequestError> {
    let mut out = Vec::new();
    io::npy::write_npy(&mut out, shape, data).map_err(RequestError::EncodeNpy)?;
    Ok(out)
}

/// A mask as PNG part `name` (file `filename`): 8-bit grey, 255 where set.
fn mask_part(
    name: OutputMap,
    filename: &'static str,
    mask: &Grid<bool>,
) -> Result<Part, RequestError> {
    let grey = mask.map(|&m| if m { 255u8 } else { 0 });
    png_part(name, filename, &DynamicImage::ImageLuma8(io::gray8(&grey)))
}

/// Part `name` of the answer: `image` as a PNG file `filename`.
fn png_part(
    name: OutputMap,
    filename: &'static str,
    image: &DynamicImage,
) -> Result<Part, RequestError> {
    Ok(Part {
        name: name.into(),
        content_type: "image/png",
        filename,
        bytes: png(image)?,
    })
}

/// The roughness map in the options' format.
fn encode_roughness(r: &Grid<f64>, opts: &FrameOptions) -> Result<Vec<u8>, RequestError> {
    let (w, h) = r.size();
    Ok(match opts.format {
        MapFormat::Png16 => png(&DynamicImage::ImageLumaA16(io::roughness_png16(r)))?,
        MapFormat::Color => png(&DynamicImage::ImageRgb8(colormap::colourise(
            r,
            0.0,
            opts.preview_max_m.unwrap_or(0.05),
        )))?,
        MapFormat::Npy => npy(
            &[h, w],
            &r.as_slice().iter().map(|&v| v as f32).collect::<Vec<_>>(),
        )?,
        MapFormat::F32 => r
            .as_slice()
            .iter()
            .flat_map(|&v| (v as f32).to_le_bytes())
            .collect(),
    })
}

/// What stood in for what `req` did not give, for `frame` (decoded from it) run in `mode`.
pub fn assumptions(req: &FrameRequest, frame: &FrameInput, mode: Mode) -> Vec<Assumption> {
    let depth_png = req
        .depth
        .as_ref()
        .is_some_and(|d| !d.starts_with(b"\x93NUMPY"));
    let scale_stated = req.camera.as_ref().is_some_and(|c| c.depth_scale.is_some());
    Assumption::of_frame(
        frame.intrinsics.is_some(),
        depth_png && !scale_stated,
        frame.mounting.is_some(),
        (mode, req.options.mode.is_some()),
    )
}

/// Encodes the pipeline's output as the options ask (the output stays the caller's, to hand
/// back to [`Pipeline::recycle`](tre_pipeline::Pipeline::recycle)); `mode` ran, with the
/// `assumed` stand-ins ([`assumptions`]).
pub fn encode_reply(
    out: &FrameOutput,
    opts: &FrameOptions,
    (mode, assumed): (Mode, Vec<Assumption>),
) -> Result<FrameReply, RequestError> {
    let (w, h) = out.roughness_m.size();
    let roughness = encode_roughness(&out.roughness_m, opts)?;
    let mut extras = Vec::new();
    let e = opts.extras;
    if let Some(d) = e.depth.then(|| out.depth_m()).flatten() {
        extras.push(Part {
            name: OutputMap::Depth.into(),
            content_type: "image/png",
            filename: "depth.png",
            bytes: png(&DynamicImage::ImageLuma16(io::depth_png16(&d)))?,
        });
    }
    if let Some(n) = e.normals.then(|| out.normals()).flatten() {
        let data: Vec<f32> = n
            .as_slice()
            .iter()
            .flat_map(|v| [v.x as f32, v.y as f32, v.z as f32])
            .collect();
        extras.push(Part {
            name: OutputMap::Normals.into(),
            content_type: "application/octet-stream",
            filename: "normals.npy",
            bytes: npy(&[h, w, 3], &data)?,
        });
    }
    if let Some(s) = e.slope.then(|| out.slope_rad()).flatten() {
        let data: Vec<f32> = s.as_slice().iter().map(|&v| v as f32).collect();
        extras.push(Part {
            name: OutputMap::Slope.into(),
            content_type: "application/octet-stream",
            filename: "slope.npy",
            bytes: npy(&[h, w], &data)?,
        });
    }
    let ok = (e.traversable || opts.traversable_bytes).then(|| out.traversable());
    if let (true, Some(ok)) = (e.traversable, &ok) {
        extras.push(mask_part(OutputMap::Traversable, "traversable.png", ok)?);
    }
    if let Some(b) = e.boundary.then(|| out.boundary()).flatten() {
        extras.push(mask_part(OutputMap::Boundary, "boundary.png", &b)?);
    }
    let traversable = match (opts.traversable_bytes, &ok) {
        (true, Some(ok)) => ok.as_slice().iter().map(|&t| u8::from(t)).collect(),
        _ => Vec::new(),
    };
    Ok(FrameReply {
        size: (w, h),
        working_size: out.working_size,
        roughness,
        format: opts.format,
        extras,
        traversable,
        traversal: Vec::new(),
        uncertainty: Vec::new(),
        timings: out.timings.clone(),
        mode,
        assumed,
        gravity: out.gravity,
        warnings: Vec::new(),
    })
}

/// Adds the sensor-noise maps the options ask for to `reply`: parts `uncertainty` and
/// `traversal` and the stream's bytes. The noise model is the options' `sensor`, else the
/// camera's; `table`: the mode's calibrated intervals, if the models have them (docs/uncertainty.md);
/// an error names what is missing (a noise model, or sensor depth in this mode). A three-state
/// map mostly unknown adds a warning saying so.
pub fn encode_sensor_maps(
    out: &FrameOutput,
    frame: &FrameInput,
    (mode, table): (Mode, Option<&IntervalTable>),
    req: &FrameRequest,
    reply: &mut FrameReply,
) -> Result<(), RequestError> {
    let opts = &req.options;
    if !opts.wants_sensor_maps() {
        return Ok(());
    }
    let spec = req.camera.as_ref().and_then(|c| c.sensor.as_ref());
    // The frame's model, from `req.noise_model()` when it was decoded.
    let model = frame.sensor;
    let described = match spec {
        Some(io::SensorSpec::Description(d)) => Some(d.as_str()),
        _ => None,
    };
    let maps = out.sensor_maps(frame, mode, model.as_ref(), described, table)?;
    // A map almost all unknown: its roughness looks like an answer and is none; said in a
    // `Warning` header, as `tre infer` says it.
    if let Some(caveat) = maps.mostly_unknown() {
        reply
            .warnings
            .push(format!("the three-state map is {caveat}"));
    }
    if opts.extras.uncertainty {
        let image = DynamicImage::ImageLumaA16(io::roughness_png16(&maps.uncertainty_m));
        let part = png_part(OutputMap::Uncertainty, "uncertainty.png", &image)?;
        reply.extras.push(part);
    }
    if opts.extras.traversal {
        let image = DynamicImage::ImageLuma8(io::traversal_gray8(&maps.traversal));
        let part = png_part(OutputMap::Traversal, "traversal.png", &image)?;
        reply.extras.push(part);
    }
    if opts.traversal_bytes {
        reply.traversal = maps.traversal.as_slice().iter().map(|&t| t as u8).collect();
    }
    if opts.uncertainty_f32 {
        let u = maps.uncertainty_m.as_slice().iter();
        reply.uncertainty = u.flat_map(|&v| (v as f32).to_le_bytes()).collect();
    }
    Ok(())
}

/// Metres per unit of the 16-bit roughness PNG.
pub const SCALE_M: f64 = ROUGHNESS_PNG_SCALE_M;

#[cfg(test)]
mod tests;
