//! On-disk formats: depth PNG (16-bit, configurable scale) and `.npy`, camera JSON, label maps,
//! and the annotator's outputs (16-bit roughness PNG with mask, float `.npy`, previews).

pub mod colormap;
pub mod npy;
pub mod sheet;

use std::fs::File;
use std::io::{BufReader, BufWriter};
use std::path::{Path, PathBuf};

use image::{DynamicImage, ImageBuffer, LumaA};
use serde::{Deserialize, Serialize};

use tre_core::geometry::{GeometryError, Grid, Intrinsics, Mounting, Vec3};
use tre_core::roughness::noise::{SensorNoise, SensorPreset};

/// Roughness on the wire: metres per unit of the 16-bit PNG (0.1 mm).
pub const ROUGHNESS_PNG_SCALE_M: f64 = 1e-4;

/// Errors of reading and writing files.
#[derive(Debug, thiserror::Error)]
pub enum IoError {
    /// An OS-level read or write failure.
    #[error(transparent)]
    Os(#[from] std::io::Error),
    /// A file that cannot be opened or read.
    // The reason is in the message, not a `source`: a report that prints the chain would
    // say it twice.
    #[error("{}: {reason}", path.display())]
    Read {
        /// The file.
        path: PathBuf,
        /// What the OS said.
        reason: std::io::Error,
    },
    /// A file that cannot be read as the image it should be (unreadable, truncated, …).
    #[error("{path}: not a readable image: {reason}")]
    Image {
        /// The file.
        path: PathBuf,
        /// What the decoder said.
        reason: String,
    },
    /// An image of the wrong kind (e.g. an 8-bit colour file given as depth).
    #[error("{path}: {reason}")]
    ImageKind {
        /// The file.
        path: PathBuf,
        /// What is wrong with it.
        reason: String,
    },
    /// A malformed `.npy` file.
    #[error(".npy: {0}")]
    Npy(String),
    /// A `.npy` whose header declares more values than allowed (checked before reading them).
    #[error(".npy: shape {shape:?} holds more values than the limit of {limit}")]
    NpyTooLarge {
        /// The declared shape.
        shape: Vec<usize>,
        /// The most values allowed.
        limit: usize,
    },
    /// A malformed camera JSON file.
    #[error("{path}: bad camera JSON: {reason}")]
    Camera {
        /// The file.
        path: PathBuf,
        /// What is wrong with it.
        reason: String,
    },
    /// Bad intrinsics values.
    #[error("{path}: {reason}")]
    Intrinsics {
        /// The file.
        path: PathBuf,
        /// The check that failed.
        reason: GeometryError,
    },
}

/// A camera JSON file: intrinsics plus optional size and depth scale, as in `shared/data`.
///
/// `sensor` names the depth sensor's noise model (docs/sensor-noise.md): a preset name
/// (`kinect_v1`, …) or `{"sigma_mm": [a, b, c]}`; any other text is kept as a description
/// and means no noise model ([`SensorSpec`]).
///
/// Other keys are allowed (files carry notes such as `source`), except ones that
/// look like a misspelt parameter (another case or separator, such as `Depth_Scale`) or like
/// the pitch or the camera height under another name (`pitch`, `tilt_rad`, `camera_height`):
/// ignoring those would leave a default in place of the value meant, so they are errors.
///
/// ```
/// use tre_io::CameraFile;
/// let ok: CameraFile = serde_json::from_str(
///     r#"{"fx": 525, "fy": 525, "cx": 319.5, "cy": 239.5, "pitch_deg": 30, "sensor": "Kinect"}"#,
/// ).unwrap();
/// assert_eq!(ok.pitch_deg, Some(30.0));
/// let e = serde_json::from_str::<CameraFile>(
///     r#"{"fx": 525, "fy": 525, "cx": 319.5, "cy": 239.5, "pitch": 30}"#,
/// ).unwrap_err();
/// assert!(e.to_string().contains("pitch_deg"), "{e}");
/// ```
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(try_from = "CameraFileKeys")]
pub struct CameraFile {
    /// Focal length x, pixels.
    pub fx: f64,
    /// Focal length y, pixels.
    pub fy: f64,
    /// Principal point x, pixels.
    pub cx: f64,
    /// Principal point y, pixels.
    pub cy: f64,
    /// Image width the intrinsics refer to, if stated.
    #[serde(default)]
    pub width: Option<usize>,
    /// Image height the intrinsics refer to, if stated.
    #[serde(default)]
    pub height: Option<usize>,
    /// Depth PNG units per metre (1000 for mm, 5000 for TUM), if stated.
    #[serde(default)]
    pub depth_scale: Option<f64>,
    /// Camera pitch below the horizon, degrees, if stated (default 60°).
    #[serde(default)]
    pub pitch_deg: Option<f64>,
    /// Camera height above the ground, metres, if stated (default 1 m).
    #[serde(default)]
    pub height_m: Option<f64>,
    /// The depth sensor: a noise model, or a description only.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub sensor: Option<SensorSpec>,
}

/// The camera file's `sensor`: a noise model, or free text (e.g. "TUM RGB-D freiburg2
/// (Kinect v1)") kept as a description, which gives no noise model.
///
/// ```
/// use tre_io::SensorSpec;
/// use tre_core::roughness::noise::{SensorNoise, SensorPreset};
/// let s: SensorSpec = serde_json::from_str(r#""kinect_v1""#).unwrap();
/// assert_eq!(s.noise(), Some(SensorNoise::Preset(SensorPreset::KinectV1)));
/// let s: SensorSpec = serde_json::from_str(r#""TUM freiburg2 (Kinect v1)""#).unwrap();
/// assert_eq!(s.noise(), None);
/// let s: SensorSpec = serde_json::from_str(r#"{"sigma_mm": [1, 0, 2]}"#).unwrap();
/// assert!(s.noise().is_some());
/// let e = serde_json::from_str::<SensorSpec>(r#"{"sigma": 3}"#).unwrap_err();
/// assert!(e.to_string().contains("sigma_mm"), "{e}");
/// ```
#[derive(Debug, Clone, PartialEq, Serialize)]
#[serde(untagged)]
pub enum SensorSpec {
    /// A preset or explicit coefficients.
    Model(SensorNoise),
    /// Text that names no preset.
    Description(String),
}

impl SensorSpec {
    /// The noise model, if this names one.
    pub fn noise(&self) -> Option<SensorNoise> {
        match self {
            Self::Model(m) => Some(*m),
            Self::Description(_) => None,
        }
    }

    /// From a JSON value: a string (preset name, else a description) or
    /// `{"sigma_mm": [a, b, c]}`; for anything else, a message naming the field.
    pub fn from_json(v: serde_json::Value) -> Result<Self, String> {
        let shape = || {
            format!(
                "sensor: expected a preset name ({}), other text (a description: no noise \
                 model) or {{\"sigma_mm\": [a, b, c]}} (σ_z = a + b·z + c·z² mm, z in metres)",
                SensorPreset::names()
            )
        };
        match v {
            serde_json::Value::String(s) => {
                Ok(s.parse::<SensorPreset>().map_or(Self::Description(s), |p| {
                    Self::Model(SensorNoise::Preset(p))
                }))
            }
            serde_json::Value::Object(o) => {
                let keys: Vec<&String> = o.keys().collect();
                let Some([a, b, c]) = o
                    .get("sigma_mm")
                    .filter(|_| keys.len() == 1)
                    .and_then(|c| serde_json::from_value::<[f64; 3]>(c.clone()).ok())
                else {
                    return Err(format!("{}; got keys {keys:?}", shape()));
                };
                SensorNoise::coefficients([a, b, c]).map(Self::Model)
            }
            _ => Err(shape()),
        }
    }
}

impl<'de> Deserialize<'de> for SensorSpec {
    fn deserialize<D: serde::Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        let v = serde_json::Value::deserialize(d)?;
        Self::from_json(v).map_err(serde::de::Error::custom)
    }
}

/// [`CameraFile`] as written, with the keys it does not know.
#[derive(Deserialize)]
struct CameraFileKeys {
    fx: f64,
    fy: f64,
    cx: f64,
    cy: f64,
    #[serde(default)]
    width: Option<usize>,
    #[serde(default)]
    height: Option<usize>,
    #[serde(default)]
    depth_scale: Option<f64>,
    #[serde(default)]
    pitch_deg: Option<f64>,
    #[serde(default)]
    height_m: Option<f64>,
    #[serde(default)]
    sensor: Option<SensorSpec>,
    #[serde(flatten)]
    other: std::collections::BTreeMap<String, serde::de::IgnoredAny>,
}

/// The keys a camera file is read for. Over HTTP and the stream they are the only keys allowed
/// ([`tre_server::request::CAMERA_KEYS`]); files read by the CLI may keep notes beside them,
/// such as `source` or `licence`.
pub const CAMERA_KEYS: [&str; 10] = [
    "fx",
    "fy",
    "cx",
    "cy",
    "width",
    "height",
    "depth_scale",
    "pitch_deg",
    "height_m",
    "sensor",
];

/// Why an unknown camera key must not be ignored, if it must not.
fn misspelt_camera_key(key: &str) -> Option<String> {
    let bare = |k: &str| -> String {
        k.chars()
            .filter(char::is_ascii_alphanumeric)
            .map(|c| c.to_ascii_lowercase())
            .collect()
    };
    let k = bare(key);
    if let Some(known) = CAMERA_KEYS.iter().find(|c| bare(c) == k) {
        return Some(format!("camera key {key:?}: did you mean {known:?}?"));
    }
    if k.starts_with("pitch") || k.starts_with("tilt") {
        return Some(format!(
            "camera key {key:?}: the pitch is \"pitch_deg\", degrees below the horizon"
        ));
    }
    let height = [
        "height",
        "cameraheight",
        "camheight",
        "mountheight",
        "mountingheight",
    ];
    if height.iter().any(|h| k.starts_with(h)) {
        return Some(format!(
            "camera key {key:?}: the camera's height is \"height_m\", metres above the ground \
             (\"height\" is the image's, in pixels)"
        ));
    }
    None
}

impl TryFrom<CameraFileKeys> for CameraFile {
    type Error = String;

    fn try_from(c: CameraFileKeys) -> Result<Self, String> {
        if let Some(e) = c.other.keys().find_map(|k| misspelt_camera_key(k)) {
            return Err(e);
        }
        Ok(Self {
            fx: c.fx,
            fy: c.fy,
            cx: c.cx,
            cy: c.cy,
            width: c.width,
            height: c.height,
            depth_scale: c.depth_scale,
            pitch_deg: c.pitch_deg,
            height_m: c.height_m,
            sensor: c.sensor,
        })
    }
}

impl CameraFile {
    /// The checked intrinsics.
    pub fn intrinsics(&self) -> Result<Intrinsics, GeometryError> {
        Intrinsics::new(self.fx, self.fy, self.cx, self.cy)
    }

    /// Whether the image size the file states, if any, is `(width, height)`; if not, why not.
    ///
    /// ```
    /// let cam: tre_io::CameraFile =
    ///     serde_json::from_str(r#"{"fx": 525, "fy": 525, "cx": 319.5, "cy": 239.5, "width": 640, "height": 480}"#).unwrap();
    /// assert!(cam.check_size((640, 480)).is_ok());
    /// assert!(cam.check_size((320, 240)).unwrap_err().contains("640×480"));
    /// ```
    pub fn check_size(&self, (width, height): (usize, usize)) -> Result<(), String> {
        let stated = (self.width.unwrap_or(width), self.height.unwrap_or(height));
        if stated == (width, height) {
            return Ok(());
        }
        let show = |v: Option<usize>| v.map_or("?".to_string(), |v| v.to_string());
        Err(format!(
            "the camera describes a {}×{} image but the frame is {width}×{height}; \
             intrinsics of another size would misplace every point",
            show(self.width),
            show(self.height)
        ))
    }

    /// The checked mounting: the stated pitch and height, each defaulting to
    /// [`Mounting::default`]'s (60°, 1 m).
    pub fn mounting(&self) -> Result<Mounting, GeometryError> {
        let default = Mounting::default();
        Mounting::new(
            self.pitch_deg.map_or(default.pitch_rad, f64::to_radians),
            self.height_m.unwrap_or(default.height_m),
        )
    }
}

/// Reads and checks a camera JSON file.
pub fn read_camera(path: &Path) -> Result<(CameraFile, Intrinsics), IoError> {
    let text = std::fs::read_to_string(path).map_err(|reason| IoError::Read {
        path: path.to_owned(),
        reason,
    })?;
    let cam: CameraFile = serde_json::from_str(&text).map_err(|e| IoError::Camera {
        path: path.to_owned(),
        reason: e.to_string(),
    })?;
    let k = cam.intrinsics().map_err(|reason| IoError::Intrinsics {
        path: path.to_owned(),
        reason,
    })?;
    Ok((cam, k))
}

/// Decodes an image file, naming the file in errors. JPEGs are decoded strictly
/// ([`decode_jpeg`]).
pub fn read_image(path: &Path) -> Result<DynamicImage, IoError> {
    let failed = |reason: String| IoError::Image {
        path: path.to_owned(),
        reason,
    };
    let bytes = std::fs::read(path).map_err(|reason| IoError::Read {
        path: path.to_owned(),
        reason,
    })?;
    if image::guess_format(&bytes).ok() == Some(image::ImageFormat::Jpeg) {
        return decode_jpeg(&bytes).map_err(failed);
    }
    image::load_from_memory(&bytes).map_err(|e| failed(e.to_string()))
}

/// Decodes a JPEG, refusing truncated or corrupt data. (`image`'s own JPEG decoding is lenient,
/// as browsers are: it fills what is missing with grey, so half a frame would pass for a whole
/// one.) Grey JPEGs come back as 8-bit grey, every other kind as RGB. One flaw is not caught:
/// scan data that ends with a proper end marker before the header's size is filled (a header
/// edited to claim more pixels) decodes with the rest filled, as the decoder reports no error.
///
/// ```
/// let img = image::RgbImage::from_fn(32, 24, |x, y| image::Rgb([x as u8 * 8, y as u8 * 10, 99]));
/// let mut jpeg = Vec::new();
/// image::codecs::jpeg::JpegEncoder::new(&mut jpeg).encode_image(&img).unwrap();
/// assert_eq!(tre_io::decode_jpeg(&jpeg).unwrap().to_rgb8().dimensions(), (32, 24));
/// assert!(tre_io::decode_jpeg(&jpeg[..jpeg.len() / 2]).is_err());
/// ```
pub fn decode_jpeg(bytes: &[u8]) -> Result<DynamicImage, String> {
    use zune_core::bytestream::ZCursor;
    use zune_core::colorspace::ColorSpace;
    use zune_core::options::DecoderOptions;
    let options = DecoderOptions::default()
        .set_strict_mode(true)
        .set_max_width(usize::MAX)
        .set_max_height(usize::MAX);
    let mut decoder = zune_jpeg::JpegDecoder::new_with_options(ZCursor::new(bytes), options);
    let failed = |e: zune_jpeg::errors::DecodeErrors| format!("not a whole, valid JPEG: {e}");
    decoder.decode_headers().map_err(failed)?;
    let grey = matches!(
        decoder.input_colorspace(),
        Some(ColorSpace::Luma | ColorSpace::LumaA)
    );
    let out = if grey {
        ColorSpace::Luma
    } else {
        ColorSpace::RGB
    };
    decoder.set_options(decoder.options().jpeg_set_out_colorspace(out));
    let pixels = decoder.decode().map_err(failed)?;
    let (w, h) = decoder
        .dimensions()
        .ok_or("not a whole, valid JPEG: no dimensions")?;
    let (w, h) = (w as u32, h as u32);
    let image = if grey {
        image::GrayImage::from_raw(w, h, pixels).map(DynamicImage::ImageLuma8)
    } else {
        image::RgbImage::from_raw(w, h, pixels).map(DynamicImage::ImageRgb8)
    };
    image.ok_or_else(|| format!("not a whole, valid JPEG: {w}×{h} pixels do not match the data"))
}

/// Reads depth in metres: a 16-bit grey PNG divided by `units_per_m` (0 = no data), or a float
/// `.npy` already in metres (0 or NaN = no data). Depth that cannot be one ([`check_depth`]:
/// no valid pixel, or a median in millimetres) is refused.
pub fn read_depth(path: &Path, units_per_m: f64) -> Result<Grid<f64>, IoError> {
    let depth = if is_npy(path) {
        npy_depth(npy::read_npy(BufReader::new(open(path)?))?)
            .map_err(|why| IoError::Npy(format!("{}: {why}", path.display())))?
    } else {
        match read_image(path)? {
            DynamicImage::ImageLuma16(img) => depth_from_luma16(img, units_per_m),
            other => {
                return Err(IoError::ImageKind {
                    path: path.to_owned(),
                    reason: format!(
                        "depth must be a 16-bit grey PNG or a float .npy, got {:?}",
                        other.color()
                    ),
                })
            }
        }
    };
    check_depth(&depth).map_err(|why| IoError::ImageKind {
        path: path.to_owned(),
        reason: if is_npy(path) {
            why
        } else {
            format!("{why} (read at {units_per_m} units per metre)")
        },
    })?;
    Ok(depth)
}

/// Depth in metres from a decoded 16-bit grey image at `units_per_m` (0 = no data).
pub fn depth_from_luma16(
    img: ImageBuffer<image::Luma<u16>, Vec<u16>>,
    units_per_m: f64,
) -> Grid<f64> {
    let (w, h) = (img.width() as usize, img.height() as usize);
    let data = img
        .into_raw()
        .into_iter()
        .map(|v| f64::from(v) / units_per_m)
        .collect();
    Grid::from_vec(w, h, data).expect("decoder sizes agree; this is a bug")
}

/// Reads labels: an 8- or 16-bit grey PNG or an integer `.npy` (0 = void).
pub fn read_labels(path: &Path) -> Result<Grid<u32>, IoError> {
    if is_npy(path) {
        let a = npy::read_npy(BufReader::new(open(path)?))?;
        let npy_error = |why: String| IoError::Npy(format!("{}: {why}", path.display()));
        if a.is_float() {
            return Err(npy_error(format!(
                "labels must be an integer .npy (class ids, 0 = void), got dtype {}",
                a.dtype
            )));
        }
        // Negative ids (often "ignore") are void too.
        return Ok(npy_grid(a).map_err(npy_error)?.map(|&v| v.max(0.0) as u32));
    }
    let img = read_image(path)?;
    let (w, h) = (img.width() as usize, img.height() as usize);
    let data: Vec<u32> = match img {
        DynamicImage::ImageLuma8(i) => i.into_raw().into_iter().map(u32::from).collect(),
        DynamicImage::ImageLuma16(i) => i.into_raw().into_iter().map(u32::from).collect(),
        other => {
            return Err(IoError::ImageKind {
                path: path.to_owned(),
                reason: format!("labels must be a grey PNG or .npy, got {:?}", other.color()),
            })
        }
    };
    Ok(Grid::from_vec(w, h, data).expect("decoder sizes agree; this is a bug"))
}

/// Reads normals from an `H × W × 3` float `.npy` (camera frame).
pub fn read_normals(path: &Path) -> Result<Grid<Vec3>, IoError> {
    let a = npy::read_npy(BufReader::new(open(path)?))?;
    let [h, w, 3] = a.shape[..] else {
        return Err(IoError::Npy(format!(
            "{}: normals must have shape (H, W, 3), got {:?}",
            path.display(),
            a.shape
        )));
    };
    let data = a
        .data
        .chunks_exact(3)
        .map(|c| Vec3::new(c[0], c[1], c[2]))
        .collect();
    Ok(Grid::from_vec(w, h, data).expect("shape checked; this is a bug"))
}

/// Opens a file for reading, naming it in the error.
fn open(path: &Path) -> Result<File, IoError> {
    File::open(path).map_err(|reason| IoError::Read {
        path: path.to_owned(),
        reason,
    })
}

fn is_npy(path: &Path) -> bool {
    path.extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("npy"))
}

/// Nearest median depth any sensor gives, metres: below it the depth scale is wrong.
pub const MIN_MEDIAN_DEPTH_M: f64 = 0.01;
/// Farthest median depth any robot's depth sensor gives, metres: above it the depth is in
/// millimetres, or the depth scale is wrong.
pub const MAX_MEDIAN_DEPTH_M: f64 = 200.0;

/// Whether a depth map in metres can be one: some valid pixel (finite, positive), and a median
/// valid depth between [`MIN_MEDIAN_DEPTH_M`] and [`MAX_MEDIAN_DEPTH_M`], which catches depth
/// in millimetres or a wrong depth scale. The median is taken over at most about 16,000
/// evenly spread pixels (a fraction of a millisecond). For why not, a message saying what to
/// check.
///
/// ```
/// use tre_core::geometry::Grid;
/// assert!(tre_io::check_depth(&Grid::new(64, 48, 1.5)).is_ok());
/// assert!(tre_io::check_depth(&Grid::new(64, 48, 0.0)).unwrap_err().contains("no valid pixel"));
/// assert!(tre_io::check_depth(&Grid::new(64, 48, 1500.0)).unwrap_err().contains("millimetres"));
/// ```
pub fn check_depth(depth_m: &Grid<f64>) -> Result<(), String> {
    let all = depth_m.as_slice();
    let step = (all.len() / 16_384).max(1);
    let mut sample: Vec<f64> = all
        .iter()
        .step_by(step)
        .copied()
        .filter(|d| d.is_finite() && *d > 0.0)
        .collect();
    if sample.is_empty() && !all.iter().any(|d| d.is_finite() && *d > 0.0) {
        let (w, h) = depth_m.size();
        return Err(format!(
            "the {w}×{h} depth map has no valid pixel (all zero, negative or not finite)"
        ));
    }
    if sample.is_empty() {
        return Ok(()); // Valid pixels, all between the sampled ones: too few to judge.
    }
    let mid = sample.len() / 2;
    let median = *sample.select_nth_unstable_by(mid, f64::total_cmp).1;
    if median > MAX_MEDIAN_DEPTH_M {
        return Err(format!(
            "the median depth is {median:.1} m, farther than any depth sensor sees: is the depth \
             in millimetres, or its depth scale (units per metre) wrong?"
        ));
    }
    if median < MIN_MEDIAN_DEPTH_M {
        return Err(format!(
            "the median depth is {median:.2e} m, nearer than any depth sensor sees: is the depth \
             scale (units per metre) wrong?"
        ));
    }
    Ok(())
}

/// Depth in metres from a `.npy`: a 2-D float array. Integer arrays are refused, since their
/// unit cannot be known (millimetres read as metres would be a thousand times off); for why not,
/// a message saying what to send instead.
pub fn npy_depth(a: npy::NpyArray) -> Result<Grid<f64>, String> {
    if !a.is_float() {
        return Err(format!(
            "depth .npy must hold float metres (float16, float32 or float64), got dtype {}: \
             for integer depth send a 16-bit PNG with its depth_scale",
            a.dtype
        ));
    }
    npy_grid(a)
}

/// A 2-D `(H, W)` array as a grid; for any other shape, why not.
pub fn npy_grid(a: npy::NpyArray) -> Result<Grid<f64>, String> {
    let [h, w] = a.shape[..] else {
        return Err(format!(
            "expected a 2-D array (H, W), got shape {:?}",
            a.shape
        ));
    };
    Grid::from_vec(w, h, a.data).map_err(|e| e.to_string())
}

/// Writes a float map as an `(H, W)` float32 `.npy` (NaN: no data).
pub fn write_npy_f32(path: &Path, grid: &Grid<f64>) -> Result<(), IoError> {
    let data: Vec<f32> = grid.as_slice().iter().map(|&v| v as f32).collect();
    npy::write_npy(
        BufWriter::new(File::create(path)?),
        &[grid.height(), grid.width()],
        &data,
    )
}

/// Writes an id map as an `(H, W)` uint32 `.npy`.
pub fn write_npy_u32(path: &Path, grid: &Grid<u32>) -> Result<(), IoError> {
    npy::write_npy(
        BufWriter::new(File::create(path)?),
        &[grid.height(), grid.width()],
        grid.as_slice(),
    )
}

/// Encodes roughness as 16-bit grey + alpha: grey = round(r / 0.1 mm) saturated at 65535
/// (6.5535 m), alpha = 65535 where valid and 0 (with grey 0) where there is no data.
pub fn roughness_png16(roughness_m: &Grid<f64>) -> ImageBuffer<LumaA<u16>, Vec<u16>> {
    let (w, h) = (roughness_m.width() as u32, roughness_m.height() as u32);
    ImageBuffer::from_fn(w, h, |x, y| {
        let r = roughness_m[(x as usize, y as usize)];
        if r.is_finite() {
            LumaA([
                (r / ROUGHNESS_PNG_SCALE_M).round().clamp(0.0, 65535.0) as u16,
                u16::MAX,
            ])
        } else {
            LumaA([0, 0])
        }
    })
}

/// Encodes a non-negative map in metres as 16-bit grey at 0.1 mm per unit (saturating at
/// 6.5535 m; non-finite: 0).
pub fn metres_png16(map_m: &Grid<f64>) -> image::ImageBuffer<image::Luma<u16>, Vec<u16>> {
    luma16(map_m, |v| {
        v.is_finite()
            .then(|| (v / ROUGHNESS_PNG_SCALE_M).round().clamp(0.0, 65535.0) as u16)
    })
}

/// A 16-bit grey image of a float map, `encode` giving each pixel's value (`None`: 0).
fn luma16(
    map: &Grid<f64>,
    encode: impl Fn(f64) -> Option<u16>,
) -> image::ImageBuffer<image::Luma<u16>, Vec<u16>> {
    image::ImageBuffer::from_fn(map.width() as u32, map.height() as u32, |x, y| {
        image::Luma([encode(map[(x as usize, y as usize)]).unwrap_or(0)])
    })
}

/// Decodes a roughness PNG written by [`roughness_png16`] back to metres (NaN: no data).
pub fn decode_roughness_png16(img: &DynamicImage) -> Grid<f64> {
    let la = img.to_luma_alpha16();
    let (w, h) = (la.width() as usize, la.height() as usize);
    let data = la
        .pixels()
        .map(|p| {
            if p[1] == 0 {
                f64::NAN
            } else {
                f64::from(p[0]) * ROUGHNESS_PNG_SCALE_M
            }
        })
        .collect();
    Grid::from_vec(w, h, data).expect("decoder sizes agree; this is a bug")
}

/// A three-state map as 8-bit grey: 0 unknown, 1 traversable, 2 hazard.
pub fn traversal_gray8(map: &Grid<tre_core::roughness::traversal::Traversal>) -> image::GrayImage {
    image::GrayImage::from_fn(map.width() as u32, map.height() as u32, |x, y| {
        image::Luma([map[(x as usize, y as usize)] as u8])
    })
}

/// Writes a boolean mask as an 8-bit PNG (255 = true).
pub fn write_mask_png(path: &Path, mask: &Grid<bool>) -> Result<(), IoError> {
    let img = image::GrayImage::from_fn(mask.width() as u32, mask.height() as u32, |x, y| {
        image::Luma([if mask[(x as usize, y as usize)] {
            255
        } else {
            0
        }])
    });
    save(path, &DynamicImage::ImageLuma8(img))
}

/// Saves an image, choosing the format from the extension.
/// PNG files use fast compression: frames are written often and read by machines.
pub fn save(path: &Path, img: &DynamicImage) -> Result<(), IoError> {
    let err = |e: image::ImageError| IoError::Image {
        path: path.to_owned(),
        reason: e.to_string(),
    };
    if path
        .extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("png"))
    {
        let out = BufWriter::new(File::create(path).map_err(|reason| IoError::Read {
            path: path.to_owned(),
            reason,
        })?);
        return encode_png(img, out).map_err(err);
    }
    img.save(path).map_err(err)
}

/// Encodes `img` as PNG into `out` with the settings [`save`] uses (fast compression,
/// adaptive filter), so a file and a network answer carry the same bytes.
pub fn encode_png(img: &DynamicImage, out: impl std::io::Write) -> Result<(), image::ImageError> {
    use image::codecs::png::{CompressionType, FilterType, PngEncoder};
    let enc = PngEncoder::new_with_quality(out, CompressionType::Fast, FilterType::Adaptive);
    img.write_with_encoder(enc)
}

/// Encodes depth (metres) as a 16-bit grey PNG in millimetres (0: no data; saturates at
/// 65.535 m).
pub fn depth_png16(depth_m: &Grid<f64>) -> image::ImageBuffer<image::Luma<u16>, Vec<u16>> {
    luma16(depth_m, |d| {
        (d > 0.0 && d.is_finite()).then(|| (d * 1000.0).round().clamp(1.0, 65535.0) as u16)
    })
}

/// An 8-bit grey image of a byte map.
pub fn gray8(map: &Grid<u8>) -> image::GrayImage {
    image::GrayImage::from_fn(map.width() as u32, map.height() as u32, |x, y| {
        image::Luma([map[(x as usize, y as usize)]])
    })
}

/// Writes normals as an `(H, W, 3)` float32 `.npy` (NaN: none).
pub fn write_normals_npy(path: &Path, normals: &Grid<Vec3>) -> Result<(), IoError> {
    let data: Vec<f32> = normals
        .as_slice()
        .iter()
        .flat_map(|n| [n.x as f32, n.y as f32, n.z as f32])
        .collect();
    npy::write_npy(
        BufWriter::new(File::create(path)?),
        &[normals.height(), normals.width(), 3],
        &data,
    )
}

/// Writes the valid points of a point map with their colours as a binary little-endian PLY
/// (x, y, z float32 metres in the camera frame; red, green, blue uchar).
pub fn write_ply(
    path: &Path,
    points: &tre_core::geometry::PointMap,
    rgb: &image::RgbImage,
) -> Result<(), IoError> {
    use std::io::Write;
    let valid: Vec<(usize, usize)> = (0..points.height())
        .flat_map(|y| (0..points.width()).map(move |x| (x, y)))
        .filter(|&(x, y)| tre_core::geometry::is_valid_point(&points[(x, y)]))
        .collect();
    let mut out = BufWriter::new(File::create(path)?);
    write!(
        out,
        "ply\nformat binary_little_endian 1.0\nelement vertex {}\nproperty float x\nproperty float y\nproperty float z\n\
         property uchar red\nproperty uchar green\nproperty uchar blue\nend_header\n",
        valid.len()
    )?;
    for (x, y) in valid {
        let p = points[(x, y)];
        for c in [p.x, p.y, p.z] {
            out.write_all(&(c as f32).to_le_bytes())?;
        }
        out.write_all(&rgb.get_pixel(x as u32, y as u32).0)?;
    }
    out.flush()?;
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn labels_are_integer_ids_and_negative_ones_are_void() {
        let dir = tempfile::tempdir().unwrap();
        let ints = dir.path().join("labels.npy");
        write_npy_u32(&ints, &Grid::from_vec(2, 1, vec![0, 7]).unwrap()).unwrap();
        assert_eq!(read_labels(&ints).unwrap().as_slice(), &[0, 7]);
        let signed = dir.path().join("signed.npy");
        npy::write_npy(File::create(&signed).unwrap(), &[1, 2], &[-1i32, 3]).unwrap();
        assert_eq!(read_labels(&signed).unwrap().as_slice(), &[0, 3]);
        // Floats would be truncated (0.7 → 0: void): refused.
        let floats = dir.path().join("floats.npy");
        write_npy_f32(&floats, &Grid::from_vec(2, 1, vec![0.7, 2.0]).unwrap()).unwrap();
        let e = read_labels(&floats).unwrap_err().to_string();
        assert!(e.contains("integer") && e.contains("<f4"), "{e}");
    }
}
