//! What a client asks for, in domain types (HTTP and stream requests both become a
//! [`FrameRequest`]), and the worker-side steps around the pipeline: decoding the bytes under
//! the limits, choosing the configuration, and encoding the maps for the answer.

use std::io::Cursor;

use image::{DynamicImage, ImageFormat, ImageReader};

pub use super::error::ImagePart;
use super::error::{CameraError, ImageError, RequestError};
use super::options::FrameOptions;
use tre_core::geometry::Grid;
use tre_core::kinds::MapFormat;
use tre_io::{self as io, CameraFile, ROUGHNESS_PNG_SCALE_M};
use tre_pipeline::{
    Assumption, FrameInput, Gravity, Mode, NormalsMethod, PipelineConfig, PipelineError,
    DEFAULT_DSAC_HYPOTHESES,
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
    pub fn check_shape(&self, part: ImagePart, w: usize, h: usize) -> Result<(), ImageError> {
        let (long, short) = (w.max(h), w.min(h));
        let size = (w, h);
        let pixels = (w as u64).saturating_mul(h as u64);
        if short == 0 {
            return Err(ImageError::NoPixels { part, size });
        }
        if long > self.max_side {
            let max_side = self.max_side;
            return Err(ImageError::SideTooLong {
                part,
                size,
                max_side,
            });
        }
        if pixels > self.max_pixels as u64 {
            let max_pixels = self.max_pixels;
            return Err(ImageError::TooManyPixels {
                part,
                size,
                max_pixels,
            });
        }
        if long > short.saturating_mul(self.max_aspect) {
            let max_aspect = self.max_aspect;
            return Err(ImageError::TooNarrow {
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
) -> Result<DynamicImage, ImageError> {
    let (format, (w, h)) = image_header(part, bytes, limits)?;
    let pixels = u64::from(w) * u64::from(h);
    if format == ImageFormat::Jpeg {
        return io::decode_jpeg(bytes).map_err(|source| ImageError::Jpeg { part, source });
    }
    let mut reader = ImageReader::with_format(Cursor::new(bytes), format);
    let mut l = image::Limits::default();
    l.max_image_width = Some(w);
    l.max_image_height = Some(h);
    l.max_alloc = Some(pixels * 16 + (1 << 20));
    reader.limits(l);
    reader
        .decode()
        .map_err(|source| ImageError::Undecodable { part, source })
}

/// The format and size of image `part` from its header, checked against the limits, without
/// decoding its pixels.
pub fn image_header(
    part: ImagePart,
    bytes: &[u8],
    limits: DecodeLimits,
) -> Result<(ImageFormat, (u32, u32)), ImageError> {
    if bytes.is_empty() {
        return Err(ImageError::EmptyImage { part });
    }
    let Some(format) = sniff(bytes) else {
        return Err(ImageError::NotAnImage { part });
    };
    let (w, h) = ImageReader::with_format(Cursor::new(bytes), format)
        .into_dimensions()
        .map_err(|source| ImageError::Undecodable { part, source })?;
    limits.check_shape(part, w as usize, h as usize)?;
    Ok((format, (w, h)))
}

/// Physical ranges of a camera sent by a client: focal lengths 1 px to 10⁶ px, pitch −90° to
/// 90°, height above the ground 1 cm to 100 m, depth scale above 0 and at most 10⁶ units per
/// metre, a stated size within the side limit. Anything else is 422 `bad_camera`.
pub fn check_camera_ranges(cam: &CameraFile, limits: DecodeLimits) -> Result<(), RequestError> {
    let within = |name, v: Option<f64>, lo, hi, unit| match v {
        Some(value) if !(value.is_finite() && (lo..=hi).contains(&value)) => {
            Err(CameraError::Range {
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
            return Err(CameraError::Side {
                name,
                side,
                max_side: limits.max_side,
            }
            .into());
        }
    }
    Ok(())
}

/// A camera JSON from a client, read as every interface reads a camera file
/// ([`CameraFile`]: the parameters of [`CAMERA_KEYS`], other keys metadata unless they look
/// like a misspelt parameter), within [`check_camera_ranges`].
///
/// [`CAMERA_KEYS`]: tre_io::CAMERA_KEYS
pub fn strict_camera(json: &[u8], limits: DecodeLimits) -> Result<CameraFile, RequestError> {
    let value: serde_json::Value = serde_json::from_slice(json).map_err(CameraError::NotJson)?;
    if !value.is_object() {
        return Err(CameraError::NotObject.into());
    }
    let cam: CameraFile = serde_json::from_value(value).map_err(CameraError::Fields)?;
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
        ImageError::EmptyImage { .. }
        | ImageError::NotAnImage { .. }
        | ImageError::Undecodable { .. }
        | ImageError::Jpeg { .. } => ImageError::NotDepth(Box::new(e)),
        _ => e,
    })?;
    match image {
        DynamicImage::ImageLuma16(img) => Ok(io::depth_from_luma16(img, units_per_m)),
        other => Err(ImageError::DepthColour {
            color: other.color(),
        }
        .into()),
    }
}

/// An RGB frame from `bytes`, refusing 16-bit grey (depth sent as colour) with 422
/// `bad_image` that says where depth goes.
fn rgb_frame(bytes: &[u8], limits: DecodeLimits) -> Result<image::RgbImage, RequestError> {
    let image = decode_image(ImagePart::Rgb, bytes, limits)?;
    if let Some(why) = io::not_rgb(image.color()) {
        return Err(ImageError::DepthAsRgb { why }.into());
    }
    Ok(image.to_rgb8())
}

/// The pipeline input for `req`: decoded images, checked camera.
pub fn decode_frame(req: &FrameRequest, limits: DecodeLimits) -> Result<FrameInput, RequestError> {
    let (intrinsics, mounting, scale) = match &req.camera {
        Some(c) => (
            Some(c.intrinsics().map_err(CameraError::Geometry)?),
            c.mounting().map_err(CameraError::Geometry)?,
            c.depth_scale.unwrap_or(1000.0),
        ),
        None => (None, None, 1000.0),
    };
    if !(scale.is_finite() && scale > 0.0) {
        return Err(CameraError::DepthScale {
            field: "camera: depth_scale",
            scale,
        }
        .into());
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
        return Err(ImageError::NoInput.into());
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

/// Metres per unit of the 16-bit roughness PNG.
pub const SCALE_M: f64 = ROUGHNESS_PNG_SCALE_M;

mod encode;
pub use encode::{assumptions, encode_reply, encode_sensor_maps};

#[cfg(test)]
mod tests;
