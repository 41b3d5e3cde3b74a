//! On-disk formats: depth PNG (16-bit, configurable scale) and `.npy`, camera JSON, label maps,
//! and the annotator's outputs (16-bit roughness PNG with mask, float `.npy`, previews).
//!
//! The everyday readers and writers are here at the root (camera JSON, depth maps and their
//! check, one frame's files, image decoding and the PNG encodings, labels, normals, `.npy` and
//! PLY output, poses).
//! Each other concern is a module of its own, named by its path: [`npy`] (the `.npy` format),
//! [`colormap`], [`previews`] and [`sheet`] (pictures for people), [`outputs`] (a frame's result
//! files), [`paths`], [`sequence`] (recorded sequence folders), [`map_files`] (the grid map's
//! files) and [`units`].

mod camera;
pub mod colormap;
mod depth;
mod frame_files;
mod images;
pub mod map_files;
pub mod map_params;
mod maps;
pub mod npy;
pub mod outputs;
pub mod paths;
pub mod previews;
pub mod sequence;
pub mod sheet;
pub mod units;

use std::fs::File;
use std::path::{Path, PathBuf};

use npy::NpyError;
use tre_core::geometry::GeometryError;

pub use camera::{
    read_camera, CameraFile, CameraKeyError, CameraSizeMismatch, SensorSpec, SensorSpecError,
    CAMERA_KEYS,
};
pub use depth::{
    check_depth, depth_from_luma16, npy_depth, read_depth, DepthError, MAX_MEDIAN_DEPTH_M,
    MIN_MEDIAN_DEPTH_M,
};
pub use frame_files::{
    read_frame_files, FrameFiles, FrameFilesError, FrameRead, DEFAULT_DEPTH_SCALE,
};
pub use images::{
    decode_jpeg, decode_roughness_png16, depth_png16, encode_png, gray8, metres_png16, not_rgb,
    read_image, roughness_png16, save, traversal_gray8, write_mask_png, ImageProblem, JpegError,
};
pub use maps::{
    npy_grid, read_labels, read_normals, read_pose, write_normals_npy, write_npy_f32,
    write_npy_u32, write_ply, PoseProblem,
};

/// Roughness on the wire: metres per unit of the 16-bit PNG (0.1 mm).
pub const ROUGHNESS_PNG_SCALE_M: f64 = 1e-4;

/// Errors of reading and writing files.
#[derive(Debug, thiserror::Error)]
pub enum IoError {
    /// An OS-level read or write failure.
    #[error(transparent)]
    Os(#[from] std::io::Error),
    /// A file that cannot be opened or read.
    // Here and below, the reason is in the message, not a `source`: a report that prints the
    // chain would say it twice. The server answers with the message alone, so it must carry
    // the reason.
    #[error("{}: {reason}", path.display())]
    Read {
        /// The file.
        path: PathBuf,
        /// What the OS said.
        reason: std::io::Error,
    },
    /// A file that cannot be created or written.
    #[error("{}: cannot write: {reason}", path.display())]
    Write {
        /// The file.
        path: PathBuf,
        /// What the OS said.
        reason: std::io::Error,
    },
    /// A file that cannot be read as the image it should be (unreadable, truncated, …).
    #[error("{}: not a readable image: {reason}", path.display())]
    Image {
        /// The file.
        path: PathBuf,
        /// What the decoder said.
        reason: ImageProblem,
    },
    /// An image that cannot be encoded into its file ([`save`]).
    #[error("{}: cannot write the image: {reason}", path.display())]
    Encode {
        /// The file.
        path: PathBuf,
        /// What the encoder said.
        reason: image::ImageError,
    },
    /// A pose file that is not 16 finite numbers.
    #[error("{}: {reason}", path.display())]
    Pose {
        /// The file.
        path: PathBuf,
        /// What is wrong.
        reason: PoseProblem,
    },
    /// An image of the wrong kind (e.g. an 8-bit colour file given as depth).
    #[error("{}: {expected}, got {got:?}", path.display())]
    ImageKind {
        /// The file.
        path: PathBuf,
        /// What the file must be, as a sentence.
        expected: &'static str,
        /// The colour type it has.
        got: image::ColorType,
    },
    /// Depth that cannot be one ([`check_depth`]); `units_per_m` is the scale a PNG was read
    /// at (none for `.npy`, which holds metres).
    #[error(
        "{}: {reason}{}",
        path.display(),
        units_per_m.map_or(String::new(), |u| format!(" (read at {u} units per metre)"))
    )]
    Depth {
        /// The file.
        path: PathBuf,
        /// What is wrong with the depth.
        reason: DepthError,
        /// Depth units per metre the file was read at, for a PNG.
        units_per_m: Option<f64>,
    },
    /// A `.npy` file that is malformed, or not the array it should be.
    #[error("{}: {reason}", path.display())]
    Npy {
        /// The file.
        path: PathBuf,
        /// What is wrong with it.
        reason: NpyError,
    },
    /// A sequence folder without a depth frame.
    #[error("{}: no .png or .npy depth frame", dir.display())]
    NoFrames {
        /// The folder searched.
        dir: PathBuf,
    },
    /// A malformed `gravity.json`.
    #[error("{}: expected {{\"gravity\": [x, y, z]}}: {reason}", path.display())]
    Gravity {
        /// The file.
        path: PathBuf,
        /// What the JSON reader said.
        reason: serde_json::Error,
    },
    /// A malformed camera JSON file.
    #[error("{}: bad camera JSON: {reason}", path.display())]
    Camera {
        /// The file.
        path: PathBuf,
        /// What the JSON reader said (a misspelt key, a missing field, …).
        reason: serde_json::Error,
    },
    /// Bad intrinsics values.
    #[error("{}: {reason}", path.display())]
    Intrinsics {
        /// The file.
        path: PathBuf,
        /// The check that failed.
        reason: GeometryError,
    },
}

/// Opens a file for reading, naming it in the error.
fn open(path: &Path) -> Result<File, IoError> {
    File::open(path).map_err(|reason| IoError::Read {
        path: path.to_owned(),
        reason,
    })
}

/// Whether `path` names a `.npy` file (by its extension, any case).
fn is_npy(path: &Path) -> bool {
    path.extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("npy"))
}
