//! One frame's files as `tre infer` names them: an RGB image, a registered depth map and a
//! camera file, read and checked against each other ([`read_frame_files`]).

use std::path::{Path, PathBuf};

use image::RgbImage;
use tre_core::geometry::{GeometryError, Grid, Intrinsics, Mounting};

use crate::{CameraFile, CameraSizeMismatch, IoError};

/// Depth PNG units per metre when neither the caller nor the camera file states them
/// (millimetres).
pub const DEFAULT_DEPTH_SCALE: f64 = 1000.0;

/// The files of one frame; any may be missing.
#[derive(Debug, Clone, Copy, Default)]
pub struct FrameFiles<'a> {
    /// The RGB frame (PNG or JPEG).
    pub rgb: Option<&'a Path>,
    /// The registered depth: a 16-bit PNG or a float `.npy` in metres.
    pub depth: Option<&'a Path>,
    /// The camera JSON.
    pub camera: Option<&'a Path>,
    /// Depth PNG units per metre, over the camera file's `depth_scale`.
    pub depth_scale: Option<f64>,
}

/// What [`read_frame_files`] read.
#[derive(Debug, Clone, Default)]
pub struct FrameRead {
    /// The RGB frame.
    pub rgb: Option<RgbImage>,
    /// The depth, metres.
    pub depth_m: Option<Grid<f64>>,
    /// The camera file and its intrinsics.
    pub camera: Option<(CameraFile, Intrinsics)>,
    /// The mounting the camera file states.
    pub mounting: Option<Mounting>,
    /// Whether a depth scale was stated (given, or the camera file's) rather than assumed.
    pub scale_stated: bool,
    /// The depth scale the depth was read with, units per metre.
    pub scale: f64,
}

/// Files of a frame that do not make one.
#[derive(Debug, thiserror::Error)]
pub enum FrameFilesError {
    /// A depth scale that is not a positive number.
    #[error("--depth-scale must be positive, got {0}")]
    DepthScale(f64),
    /// A 16-bit grey image given as the RGB frame.
    #[error("{}: {why} (--depth, with --camera or --depth-scale)", path.display())]
    NotRgb {
        /// The image.
        path: PathBuf,
        /// Why it is not one.
        why: &'static str,
    },
    /// A camera file whose pitch or height is out of range.
    #[error("camera pitch or height")]
    Mounting(#[source] GeometryError),
    /// A camera file stating another size than the frame's.
    #[error("camera {}", path.display())]
    CameraSize {
        /// The camera file.
        path: PathBuf,
        /// The sizes.
        #[source]
        source: CameraSizeMismatch,
    },
    /// Intrinsics implausible for the frame's size.
    #[error("camera {}", path.display())]
    Intrinsics {
        /// The camera file.
        path: PathBuf,
        /// Why.
        #[source]
        source: GeometryError,
    },
    /// A file that does not read.
    #[error(transparent)]
    Io(#[from] IoError),
}

/// Reads the frame's files: the depth at the scale given, else the camera file's, else
/// [`DEFAULT_DEPTH_SCALE`]; the camera's intrinsics checked against the frame's size (the RGB
/// image's, else the depth's).
///
/// # Errors
///
/// [`FrameFilesError`].
pub fn read_frame_files(files: &FrameFiles<'_>) -> Result<FrameRead, FrameFilesError> {
    let camera = files.camera.map(crate::read_camera).transpose()?;
    let stated = (files.depth_scale).or(camera.as_ref().and_then(|(c, _)| c.depth_scale));
    let scale = stated.unwrap_or(DEFAULT_DEPTH_SCALE);
    if !(scale.is_finite() && scale > 0.0) {
        return Err(FrameFilesError::DepthScale(scale));
    }
    let rgb = match files.rgb {
        Some(path) => {
            let image = crate::read_image(path)?;
            if let Some(why) = crate::not_rgb(image.color()) {
                let path = path.to_owned();
                return Err(FrameFilesError::NotRgb { path, why });
            }
            Some(image.to_rgb8())
        }
        None => None,
    };
    let depth_m = files
        .depth
        .map(|path| crate::read_depth(path, scale))
        .transpose()?;
    let mounting = match &camera {
        Some((c, _)) => c.mounting().map_err(FrameFilesError::Mounting)?,
        None => None,
    };
    let size = match (&rgb, &depth_m) {
        (Some(rgb), _) => Some((rgb.width() as usize, rgb.height() as usize)),
        (None, depth) => depth.as_ref().map(Grid::size),
    };
    if let (Some((c, k)), Some(path), Some((w, h))) = (&camera, files.camera, size) {
        let path = path.to_owned();
        if let Err(source) = c.check_size((w, h)) {
            return Err(FrameFilesError::CameraSize { path, source });
        }
        k.check_for(w, h)
            .map_err(|source| FrameFilesError::Intrinsics { path, source })?;
    }
    Ok(FrameRead {
        rgb,
        depth_m,
        camera,
        mounting,
        scale_stated: stated.is_some(),
        scale: stated.unwrap_or(DEFAULT_DEPTH_SCALE),
    })
}
