//! Camera JSON files: intrinsics, image size, depth scale, mounting and the depth sensor, with
//! the errors that name what is wrong in one.

use std::path::Path;

use serde::{Deserialize, Serialize};

use tre_core::geometry::{GeometryError, Intrinsics, Mounting};
use tre_core::roughness::noise::{
    CoefficientsError, SensorNoise, SensorPreset, StereoRig, StereoRigError,
};

use super::IoError;

/// A camera JSON file: intrinsics plus optional size and depth scale, as in `shared/data`.
///
/// `sensor` names the depth sensor's noise model (docs/sensor-noise.md): a preset name
/// (`kinect_v1`, …) or `{"sigma_mm": [a, b, c]}`; any other text is kept as a description
/// and means no noise model ([`SensorSpec`]).
///
/// Other keys are metadata (files carry notes such as `source`, `licence`, `frames`), read past
/// by every interface (`tre infer`, `tre eval`, `tre client`, HTTP), except ones that look like
/// a misspelt parameter (another case or separator, such as `Depth_Scale`; within one edit of
/// a two-letter key, such as `fz`, or two of a longer one, such as `depth_sacle`) or like the
/// pitch or the camera height under another name (`pitch`, `tilt_rad`, `camera_height`), or
/// lens-distortion coefficients not all zero (`distortion`, `D`, `k1`, …; the depth is read
/// through a pinhole): ignoring those would leave a default in place of the value meant, so
/// they are errors.
///
/// ```
/// use tre_io::CameraFile;
/// let ok: CameraFile = serde_json::from_str(
///     r#"{"fx": 525, "fy": 525, "cx": 319.5, "cy": 239.5, "pitch_deg": 30, "sensor": "Kinect v1"}"#,
/// ).unwrap();
/// assert_eq!(ok.pitch_deg, Some(30.0));
/// let e = serde_json::from_str::<CameraFile>(
///     r#"{"fx": 525, "fy": 525, "cx": 319.5, "cy": 239.5, "pitch": 30}"#,
/// ).unwrap_err();
/// assert!(e.to_string().contains("pitch_deg"), "{e}");
/// // A typo is named; notes are metadata.
/// let e = serde_json::from_str::<CameraFile>(
///     r#"{"fx": 525, "fy": 525, "cx": 319.5, "cy": 239.5, "depth_sacle": 5000}"#,
/// ).unwrap_err();
/// assert!(e.to_string().contains("\"depth_scale\""), "{e}");
/// let notes: CameraFile = serde_json::from_str(
///     r#"{"fx": 525, "fy": 525, "cx": 319.5, "cy": 239.5, "licence": "CC BY 4.0", "notes": "x"}"#,
/// ).unwrap();
/// assert_eq!(notes.fx, 525.0);
/// // A lens that distorts is refused; a rectified image's zeros are metadata.
/// let e = serde_json::from_str::<CameraFile>(
///     r#"{"fx": 525, "fy": 525, "cx": 319.5, "cy": 239.5, "dist_coeffs": [0.04, -0.1, 0, 0]}"#,
/// ).unwrap_err();
/// assert!(e.to_string().contains("undistort"), "{e}");
/// let zeros = r#"{"fx": 525, "fy": 525, "cx": 319.5, "cy": 239.5, "D": [0, 0, 0, 0, 0]}"#;
/// assert!(serde_json::from_str::<CameraFile>(zeros).is_ok());
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
/// let e = serde_json::from_str::<SensorSpec>(r#"{"sigma_mm": [1, 0, -1]}"#).unwrap_err();
/// assert!(e.to_string().starts_with("sensor.sigma_mm [1.0, 0.0, -1.0]: σ_z"), "{e}");
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
    /// `{"sigma_mm": [a, b, c]}`; for anything else, an error naming the field.
    pub fn from_json(v: serde_json::Value) -> Result<Self, SensorSpecError> {
        match v {
            serde_json::Value::String(s) => match s.parse::<SensorPreset>() {
                Ok(p) => Ok(Self::Model(SensorNoise::Preset(p))),
                // One word is meant as a preset's name: a misspelt or unknown one would leave
                // the frame without a noise model.
                Err(_) if looks_like_a_name(&s) => Err(SensorSpecError::UnknownPreset { name: s }),
                Err(_) => Ok(Self::Description(s)),
            },
            serde_json::Value::Object(o) if o.contains_key("stereo") && o.len() == 1 => {
                let rig: StereoRig = serde_json::from_value(o["stereo"].clone())
                    .map_err(|reason| SensorSpecError::StereoFields { reason })?;
                let stereo = rig
                    .checked()
                    .map_err(|reason| SensorSpecError::StereoRig { reason })?;
                Ok(Self::Model(SensorNoise::Stereo { stereo }))
            }
            serde_json::Value::Object(o) => {
                let keys: Vec<String> = o.keys().cloned().collect();
                let Some(sigma_mm) = o
                    .get("sigma_mm")
                    .filter(|_| keys.len() == 1)
                    .and_then(|c| serde_json::from_value::<[f64; 3]>(c.clone()).ok())
                else {
                    return Err(SensorSpecError::NotASensor { keys: Some(keys) });
                };
                SensorNoise::coefficients(sigma_mm)
                    .map(Self::Model)
                    .map_err(|reason| SensorSpecError::Coefficients { sigma_mm, reason })
            }
            _ => Err(SensorSpecError::NotASensor { keys: None }),
        }
    }
}

/// True for text that reads as a name (one word of letters, digits, `_`, `-`, `.`), not a
/// description.
fn looks_like_a_name(s: &str) -> bool {
    !s.is_empty()
        && s.chars()
            .all(|c| c.is_ascii_alphanumeric() || matches!(c, '_' | '-' | '.'))
}

/// Why a camera file's `sensor` names no sensor.
#[derive(Debug, thiserror::Error)]
pub enum SensorSpecError {
    /// Neither text nor `{"sigma_mm": [a, b, c]}` (`keys`: an object's keys, if it was one).
    #[error(
        "sensor: expected a preset name ({}), other text (a description: no noise model), \
         {{\"sigma_mm\": [a, b, c]}} (σ_z = a + b·z + c·z² mm, z in metres) or {{\"stereo\": \
         {{\"baseline_m\", \"focal_px\", \"step_px\", \"block_px\"}}}}{}",
        SensorPreset::names(),
        keys.as_ref().map_or(String::new(), |k| format!("; got keys {k:?}"))
    )]
    NotASensor {
        /// The keys of the object given, if an object was given.
        keys: Option<Vec<String>>,
    },
    /// Coefficients that do not make a noise model (negative σ, not finite, …).
    // The reason is the message, not a `source`: a report that prints the chain would say it
    // twice.
    #[error("{reason}")]
    Coefficients {
        /// The coefficients given.
        sigma_mm: [f64; 3],
        /// The check that failed; its message names `sensor.sigma_mm`.
        reason: CoefficientsError,
    },
    /// One word that is no preset's name.
    #[error(
        "sensor {name:?} is no preset: the presets are {}; give one of them, \
         {{\"sigma_mm\": [a, b, c]}}, a stereo rig, or a description in words (no noise model)",
        SensorPreset::names()
    )]
    UnknownPreset {
        /// The name given.
        name: String,
    },
    /// A stereo rig whose fields do not read (one missing, unknown or not a number).
    // The reason is in the message, not a `source` (as for `Coefficients`).
    #[error("sensor.stereo: {reason}")]
    StereoFields {
        /// Why, as serde says it (its message names the field).
        reason: serde_json::Error,
    },
    /// A stereo rig with a field that is not a positive number.
    #[error("sensor.stereo: {reason}")]
    StereoRig {
        /// The check that failed; its message names the field.
        reason: StereoRigError,
    },
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
    other: std::collections::BTreeMap<String, serde_json::Value>,
}

/// The keys a camera file is read for. Every other key is metadata, read past, unless it looks
/// like a misspelt one ([`CameraFile`]).
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

/// A camera key that looks like a misspelt parameter, or like the pitch or the camera height
/// under another name: ignoring it would leave a default in place of the value meant.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum CameraKeyError {
    /// Another spelling (case, separators) of a known key.
    #[error("camera key {key:?}: did you mean {known:?}?")]
    Misspelt {
        /// The key as written.
        key: String,
        /// The known key it spells.
        known: &'static str,
    },
    /// The pitch under another name.
    #[error("camera key {key:?}: the pitch is \"pitch_deg\", degrees below the horizon")]
    Pitch {
        /// The key as written.
        key: String,
    },
    /// The camera's height under another name.
    #[error(
        "camera key {key:?}: the camera's height is \"height_m\", metres above the ground \
         (\"height\" is the image's, in pixels)"
    )]
    Height {
        /// The key as written.
        key: String,
    },
    /// Lens distortion coefficients, not all zero: the depth is read through a pinhole.
    #[error(
        "camera key {key:?}: lens distortion is not modelled (the depth is read through the \
         pinhole fx, fy, cx, cy): undistort the depth first and give the undistorted image's \
         intrinsics; if the image is already rectified, leave the coefficients out"
    )]
    Distortion {
        /// The key as written.
        key: String,
    },
}

/// A lens-distortion key (`distortion`, `dist_coeffs`, `D`, `k1`, `p2`, `coeffs`, …) whose value
/// holds a number other than zero: read past, it would leave the lens's distortion in the
/// points. Zeros (a rectified image's) and the model's name are metadata.
fn distortion_key(key: &str, value: &serde_json::Value) -> Option<CameraKeyError> {
    fn nonzero(v: &serde_json::Value) -> bool {
        match v {
            serde_json::Value::Number(n) => n.as_f64().is_some_and(|x| x != 0.0),
            serde_json::Value::Array(a) => a.iter().any(nonzero),
            serde_json::Value::Object(o) => o.values().any(nonzero),
            _ => false,
        }
    }
    let k = bare_key(key);
    let named = k.starts_with("dist")
        || [
            "d", "coeffs", "k1", "k2", "k3", "k4", "k5", "k6", "p1", "p2",
        ]
        .contains(&k.as_str());
    (named && nonzero(value)).then(|| CameraKeyError::Distortion {
        key: key.to_owned(),
    })
}

/// Levenshtein distance of two ASCII strings.
fn edit_distance(a: &str, b: &str) -> usize {
    let b = b.as_bytes();
    let mut row: Vec<usize> = (0..=b.len()).collect();
    for (i, ca) in a.bytes().enumerate() {
        let mut diag = row[0];
        row[0] = i + 1;
        for (j, &cb) in b.iter().enumerate() {
            let up = row[j + 1];
            row[j + 1] = (up + 1).min(row[j] + 1).min(diag + usize::from(ca != cb));
            diag = up;
        }
    }
    row[b.len()]
}

/// A key's letters and digits, lower case: `Depth_Scale` and `depth-scale` read `depthscale`.
fn bare_key(key: &str) -> String {
    key.chars()
        .filter(char::is_ascii_alphanumeric)
        .map(|c| c.to_ascii_lowercase())
        .collect()
}

/// Why an unknown camera key must not be ignored, if it must not.
fn misspelt_camera_key(key: &str) -> Option<CameraKeyError> {
    let k = bare_key(key);
    let key = key.to_owned();
    // The same letters in another case or with other separators, or within one edit of a
    // two-letter key (`fz`) and two of a longer one (`depth_sacle`): a typo, not a note.
    let near = |c: &str| {
        let c = bare_key(c);
        c == k || edit_distance(&c, &k) <= if c.len() <= 2 { 1 } else { 2 }
    };
    if let Some(known) = CAMERA_KEYS.iter().find(|c| near(c)) {
        return Some(CameraKeyError::Misspelt { key, known });
    }
    if k.starts_with("pitch") || k.starts_with("tilt") {
        return Some(CameraKeyError::Pitch { key });
    }
    let height = [
        "height",
        "cameraheight",
        "camheight",
        "mountheight",
        "mountingheight",
    ];
    if height.iter().any(|h| k.starts_with(h)) {
        return Some(CameraKeyError::Height { key });
    }
    None
}

impl TryFrom<CameraFileKeys> for CameraFile {
    type Error = CameraKeyError;

    fn try_from(c: CameraFileKeys) -> Result<Self, CameraKeyError> {
        let refused = c
            .other
            .iter()
            .find_map(|(k, v)| misspelt_camera_key(k).or_else(|| distortion_key(k, v)));
        if let Some(e) = refused {
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
    /// let e = cam.check_size((320, 240)).unwrap_err();
    /// assert_eq!((e.camera_width, e.frame_width), (Some(640), 320));
    /// assert!(e.to_string().contains("640×480"));
    /// ```
    pub fn check_size(&self, (width, height): (usize, usize)) -> Result<(), CameraSizeMismatch> {
        let stated = (self.width.unwrap_or(width), self.height.unwrap_or(height));
        if stated == (width, height) {
            return Ok(());
        }
        Err(CameraSizeMismatch {
            camera_width: self.width,
            camera_height: self.height,
            frame_width: width,
            frame_height: height,
        })
    }

    /// The checked mounting, if the file states one: the pitch (`pitch_deg`), with the height
    /// defaulting to [`Mounting::default`]'s 1 m when only the pitch is stated (slope needs the
    /// pitch alone). A height without a pitch is an error: it would leave a guessed pitch in
    /// charge of slope.
    ///
    /// ```
    /// let cam: tre_io::CameraFile =
    ///     serde_json::from_str(r#"{"fx": 525, "fy": 525, "cx": 319.5, "cy": 239.5}"#).unwrap();
    /// assert_eq!(cam.mounting().unwrap(), None);
    /// ```
    pub fn mounting(&self) -> Result<Option<Mounting>, GeometryError> {
        let default = Mounting::default();
        match (self.pitch_deg, self.height_m) {
            (None, None) => Ok(None),
            (None, Some(_)) => Err(GeometryError::HeightWithoutPitch),
            (Some(p), h) => Mounting::new(p.to_radians(), h.unwrap_or(default.height_m)).map(Some),
        }
    }
}

/// A camera file that states another image size than the frame's.
#[derive(Debug, Clone, Copy, PartialEq, Eq, thiserror::Error)]
#[error(
    "the camera describes a {}×{} image but the frame is {frame_width}×{frame_height}; \
     intrinsics of another size would misplace every point",
    show(*camera_width),
    show(*camera_height)
)]
pub struct CameraSizeMismatch {
    /// The width the camera states, if it does.
    pub camera_width: Option<usize>,
    /// The height the camera states, if it does.
    pub camera_height: Option<usize>,
    /// The frame's width.
    pub frame_width: usize,
    /// The frame's height.
    pub frame_height: usize,
}

/// A stated size, or `?`.
fn show(v: Option<usize>) -> String {
    v.map_or("?".to_string(), |v| v.to_string())
}

/// Reads and checks a camera JSON file.
pub fn read_camera(path: &Path) -> Result<(CameraFile, Intrinsics), IoError> {
    let text = std::fs::read_to_string(path).map_err(|reason| IoError::Read {
        path: path.to_owned(),
        reason,
    })?;
    let cam: CameraFile = serde_json::from_str(&text).map_err(|reason| IoError::Camera {
        path: path.to_owned(),
        reason,
    })?;
    let k = cam.intrinsics().map_err(|reason| IoError::Intrinsics {
        path: path.to_owned(),
        reason,
    })?;
    Ok((cam, k))
}
