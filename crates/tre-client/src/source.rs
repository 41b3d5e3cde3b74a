//! Frame sources for the client: a folder of images (with an optional folder of depth frames of
//! the same stems), a folder of depth frames alone (the geometric mode), each with optional
//! camera-to-world poses (a folder of `<stem>.txt` or a pose-a-line file), or a video file or V4L2 camera decoded by an `ffmpeg`
//! process (spawned when `ffmpeg` is on `PATH`; no video library is linked in).
//!
//! Frames are sent as the encoded bytes they are read as (PNG or JPEG): nothing is decoded or
//! re-encoded on the robot.

use std::io;
use std::path::{Path, PathBuf};
use std::process::ExitStatus;

use super::ClientError;
use ffmpeg::MAX_PNG_BYTES;

mod ffmpeg;
mod folder;
mod poses;
#[cfg(test)]
mod tests;

pub use ffmpeg::{find_executable, read_png, FfmpegSource};
pub use folder::FolderSource;

/// Where frames come from.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum SourceSpec {
    /// Every `.png`, `.jpg` and `.jpeg` file of `frames`, in file-name order (byte order:
    /// zero-pad numbers). With `depth`, frame `frames/<stem>.<ext>` takes its depth from
    /// `depth/<stem>.png` (16-bit) or `depth/<stem>.npy`; every frame must have one.
    Folder {
        /// The frames.
        frames: PathBuf,
        /// Depth frames with the same stems.
        depth: Option<PathBuf>,
        /// Camera-to-world poses: a folder of `<stem>.txt`, or a file of one pose a line in
        /// the frames' order (16, 12 or 8 numbers a line).
        poses: Option<PathBuf>,
    },
    /// Every `.png` (16-bit) and `.npy` file of `depth`, in file-name order, sent as
    /// depth-only frames (no colour: the geometric mode).
    Depth {
        /// The depth frames.
        depth: PathBuf,
        /// Camera-to-world poses, as for [`SourceSpec::Folder`].
        poses: Option<PathBuf>,
    },
    /// A video file, decoded by `ffmpeg`; frames are named `<file stem>_<index>`.
    Video(PathBuf),
    /// A V4L2 camera (`/dev/videoN`) read by `ffmpeg`; the newest frame wins (frames the
    /// client has no time for are skipped), named `<device>_<index>`.
    Device(PathBuf),
}

/// What is wrong with a frame source's file or folder ([`ClientError::Source`]).
// The cause is in the message, not a `source`: a report that prints the chain would say it
// twice.
#[derive(Debug, thiserror::Error)]
pub enum SourceProblem {
    /// It cannot be listed or read.
    #[error("{0}")]
    Io(io::Error),
    /// A folder without frames.
    #[error("no .png, .jpg or .jpeg files")]
    NoImages,
    /// A frame without its depth file.
    #[error("no depth for frame {stem}: expected {stem}.png or {stem}.npy")]
    NoDepth {
        /// The frame's file stem.
        stem: String,
    },
    /// A video path that is not a file.
    #[error("no such video file")]
    NoVideo,
    /// A folder of depth frames without any.
    #[error("no .png or .npy depth files")]
    NoDepthFiles,
    /// A frame without its pose file.
    #[error("no pose for frame {stem}: expected {stem}.txt")]
    NoPose {
        /// The frame's file stem.
        stem: String,
    },
    /// A pose file that is not a pose.
    #[error("{0}")]
    Pose(Box<tre_io::IoError>),
    /// A line of a pose list that is not a pose.
    #[error("line {line}: {reason}")]
    PoseLine {
        /// The line, from 1.
        line: usize,
        /// Why.
        reason: PoseLineProblem,
    },
    /// A pose list shorter than the frames.
    #[error("{poses} poses for {frames} frames")]
    TooFewPoses {
        /// Poses in the list.
        poses: usize,
        /// Frames of the folder.
        frames: usize,
    },
}

/// Why a line of a pose list is not a pose ([`SourceProblem::PoseLine`]).
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum PoseLineProblem {
    /// Text that is not all numbers.
    #[error("not numbers ({0})")]
    NotNumbers(std::num::ParseFloatError),
    /// A number that is NaN or infinite.
    #[error("a number that is not finite")]
    NotFinite,
    /// A quaternion of length zero.
    #[error("a zero quaternion")]
    ZeroQuaternion,
    /// Another count of numbers than 16, 12 or 8.
    #[error("{0} numbers: expected 16 (4×4), 12 (3×4) or 8 (t tx ty tz qx qy qz qw)")]
    Count(usize),
}

/// What went wrong with `ffmpeg` ([`ClientError::Ffmpeg`]).
// The cause is in the message, not a `source` (as [`SourceProblem`]).
#[derive(Debug, thiserror::Error)]
pub enum FfmpegProblem {
    /// The process cannot be started.
    #[error("cannot start ffmpeg: {0}")]
    Start(io::Error),
    /// The process came without one of its pipes (`stdout`, `stderr`).
    #[error("no {0} pipe")]
    NoPipe(&'static str),
    /// A thread reading its pipes cannot be started.
    #[error("cannot start a thread ({name}): {reason}")]
    Thread {
        /// The thread.
        name: &'static str,
        /// Why.
        reason: io::Error,
    },
    /// It ended cleanly without a frame.
    #[error("no frames decoded")]
    NoFrames,
    /// It failed; the end of what it wrote on stderr says why.
    #[error("{status}: {}", .stderr_tail.trim())]
    Exited {
        /// Its exit status.
        status: ExitStatus,
        /// The last few kilobytes of its stderr.
        stderr_tail: String,
    },
    /// Its exit status cannot be had.
    #[error("waiting for it: {0}")]
    Wait(io::Error),
    /// Its output is not a stream of PNG images.
    #[error("{0}")]
    Stream(PngStreamError),
}

/// Why a stream of concatenated PNGs cannot be split ([`read_png`]).
// The cause is in the message, not a `source` (as [`SourceProblem`]).
#[derive(Debug, thiserror::Error)]
pub enum PngStreamError {
    /// Bytes that do not start with the PNG signature.
    #[error("the stream is not a sequence of PNG images")]
    NotPng,
    /// The stream ended part way through an image.
    #[error("the stream ended inside a PNG")]
    Truncated,
    /// An image larger than the limit (256 MiB).
    #[error("a PNG larger than {MAX_PNG_BYTES} bytes")]
    TooLarge,
    /// Reading the stream failed.
    #[error("{0}")]
    Read(io::Error),
}

/// One frame from a source.
#[derive(Debug, Clone, PartialEq)]
pub struct SourceFrame {
    /// A name for outputs: the file stem, or `<video>_<index>`.
    pub name: String,
    /// PNG or JPEG bytes (empty for a depth-only frame).
    pub image: Vec<u8>,
    /// Depth bytes (16-bit PNG or `.npy`), if the source has depth.
    pub depth: Option<Vec<u8>>,
    /// Camera-to-world pose, 4×4 row by row, if the source has poses.
    pub pose: Option<Vec<f64>>,
}

/// An open frame source: an iterator of frames, ending at the end of the folder or video.
#[derive(Debug)]
pub enum FrameSource {
    /// A folder listing.
    Folder(FolderSource),
    /// An `ffmpeg` process.
    Ffmpeg(FfmpegSource),
}

impl FrameSource {
    /// Opens `spec`: lists and pairs a folder, or starts `ffmpeg`.
    pub fn open(spec: &SourceSpec) -> Result<Self, ClientError> {
        Ok(match spec {
            SourceSpec::Folder {
                frames,
                depth,
                poses,
            } => Self::Folder(FolderSource::open(
                frames,
                depth.as_deref(),
                poses.as_deref(),
            )?),
            SourceSpec::Depth { depth, poses } => {
                Self::Folder(FolderSource::depth_only(depth, poses.as_deref())?)
            }
            SourceSpec::Video(path) => Self::Ffmpeg(FfmpegSource::video(path)?),
            SourceSpec::Device(path) => Self::Ffmpeg(FfmpegSource::device(path)?),
        })
    }
}

impl Iterator for FrameSource {
    type Item = Result<SourceFrame, ClientError>;

    fn next(&mut self) -> Option<Self::Item> {
        match self {
            Self::Folder(f) => f.next(),
            Self::Ffmpeg(f) => f.next(),
        }
    }
}

pub(super) fn source_err(path: &Path, reason: SourceProblem) -> ClientError {
    ClientError::Source {
        path: path.to_owned(),
        reason,
    }
}

fn stem(path: &Path) -> String {
    path.file_stem()
        .map_or_else(|| "frame".to_owned(), |s| s.to_string_lossy().into_owned())
}
