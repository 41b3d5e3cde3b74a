//! Errors of the evaluation, by concern: an input JSON file, the splits, finding real frames,
//! loading one frame, running one configuration on it, and the runs over many frames (the
//! real-frame benchmark, the region scoring and the calibration samples; the synthetic split).
//! Each names what it was doing and keeps the error beneath as its `source`, so that
//! `{:#}` prints `frame: what failed`.

use std::path::{Path, PathBuf};

use serde::de::DeserializeOwned;
use tre_core::geometry::GeometryError;
use tre_core::kinds::Mode;
use tre_core::roughness::RoughnessError;
use tre_io::{DepthError, IoError};
use tre_pipeline::PipelineError;

/// A JSON input file (a splits, floor-box or regions file, a dataset's manifest) that does not
/// read or parse.
#[derive(Debug, thiserror::Error)]
pub enum JsonFileError {
    /// The file cannot be read.
    #[error("reading {}", path.display())]
    Read {
        /// The file.
        path: PathBuf,
        /// What the OS said.
        #[source]
        source: std::io::Error,
    },
    /// The file is not the JSON it should be.
    #[error("parsing {}", path.display())]
    Parse {
        /// The file.
        path: PathBuf,
        /// What the parser said.
        #[source]
        source: serde_json::Error,
    },
}

/// Reads the text of `path`.
pub(crate) fn read_text(path: &Path) -> Result<String, JsonFileError> {
    std::fs::read_to_string(path).map_err(|source| JsonFileError::Read {
        path: path.to_owned(),
        source,
    })
}

/// Reads and parses the JSON file `path`.
pub(crate) fn read_json<T: DeserializeOwned>(path: &Path) -> Result<T, JsonFileError> {
    serde_json::from_str(&read_text(path)?).map_err(|source| JsonFileError::Parse {
        path: path.to_owned(),
        source,
    })
}

/// A splits file that does not hold, or a sequence it does not place.
#[derive(Debug, thiserror::Error)]
pub enum SplitsError {
    /// The file does not read or parse.
    #[error(transparent)]
    File(#[from] JsonFileError),
    /// A part whose `from` is not below its `to`.
    #[error("{}: {sequence}: a part with from ≥ to", path.display())]
    PartOrder {
        /// The splits file.
        path: PathBuf,
        /// The sequence of that part.
        sequence: String,
    },
    /// A sequence the file does not list (every sequence scored must have a split).
    #[error("sequence {sequence:?} has no split in the splits file; add it there")]
    Unsplit {
        /// The sequence's name.
        sequence: String,
    },
}

/// Real frames that cannot be found or described (the folder layout of [`crate::real`]).
#[derive(Debug, thiserror::Error)]
pub enum FramesError {
    /// A folder that cannot be listed.
    #[error("reading {}", dir.display())]
    ReadDir {
        /// The folder.
        dir: PathBuf,
        /// What the OS said.
        #[source]
        source: std::io::Error,
    },
    /// Neither the folder nor any folder in it holds `intrinsics.json`.
    #[error(
        "{}: no intrinsics.json in it or in its folders (see `tre eval --help` for the layout)",
        dir.display()
    )]
    NoSequence {
        /// The folder given.
        dir: PathBuf,
    },
    /// Sequence folders without a frame.
    #[error("{}: no RGB-D frames found", dir.display())]
    NoFrames {
        /// The folder given.
        dir: PathBuf,
    },
    /// A camera file that does not read.
    #[error(transparent)]
    Camera(#[from] IoError),
    /// A file (a camera file, the splits file) that does not read or parse.
    #[error(transparent)]
    File(#[from] JsonFileError),
    /// A camera file whose `"frames"` list is not pairs of file names.
    #[error("{}: \"frames\"", path.display())]
    FrameList {
        /// The camera file.
        path: PathBuf,
        /// What the parser said.
        #[source]
        source: serde_json::Error,
    },
    /// A file the camera file's `"frames"` lists that is not there.
    #[error("{}: listed frame file {} is missing", sequence.display(), file.display())]
    MissingFile {
        /// The sequence folder.
        sequence: PathBuf,
        /// The file.
        file: PathBuf,
    },
    /// The splits file does not hold, or does not place a sequence.
    #[error(transparent)]
    Splits(#[from] SplitsError),
    /// No frame left in the split asked for.
    #[error("{}: no frame is in split {split:?}", path.display())]
    EmptySplit {
        /// The splits file.
        path: PathBuf,
        /// The split asked for.
        split: String,
    },
}

/// A frame that does not load: its files, its camera, the spec on its depth.
#[derive(Debug, thiserror::Error)]
pub enum FrameLoadError {
    /// A file (image, depth, pose, camera, ground truth) that does not read.
    #[error(transparent)]
    Io(#[from] IoError),
    /// A camera file whose mounting does not hold.
    #[error(transparent)]
    Mounting(#[from] GeometryError),
    /// The spec cannot be computed on the depth.
    #[error(transparent)]
    Spec(#[from] RoughnessError),
    /// A depth-sensor model's depth that fails the depth checks.
    #[error("{}", path.display())]
    SensorDepth {
        /// The depth file.
        path: PathBuf,
        /// The check it fails.
        #[source]
        source: DepthError,
    },
}

/// One configuration that fails on a loaded frame, or whose output cannot be scored.
#[derive(Debug, thiserror::Error)]
pub enum RunError {
    /// The pipeline fails on the frame.
    #[error(transparent)]
    Pipeline(#[from] PipelineError),
    /// The output and the truth cannot be compared (their sizes differ).
    #[error(transparent)]
    Score(#[from] RoughnessError),
    /// A frame without the sensor depth it is scored on.
    #[error("the frame has no sensor depth to score against")]
    NoSensorDepth,
    /// A mode whose output lacks the depth it predicts.
    #[error("the {mode} mode's output has no depth")]
    NoPredictedDepth {
        /// The mode.
        mode: Mode,
    },
}

/// A run over real frames (the benchmark, the region scoring, the calibration samples) that
/// stops at a frame.
#[derive(Debug, thiserror::Error)]
pub enum BenchError {
    /// The frame does not load.
    #[error("{frame}")]
    Load {
        /// The frame's name (`sequence/depth path`).
        frame: String,
        /// Why.
        #[source]
        source: Box<FrameLoadError>,
    },
    /// A configuration fails on the frame.
    #[error("{frame}: {row}")]
    Run {
        /// The frame's name (`sequence/depth path`).
        frame: String,
        /// The configuration's key (`mode:label`).
        row: String,
        /// Why.
        #[source]
        source: Box<RunError>,
    },
    /// A frame's contact sheet cannot be written.
    #[error(transparent)]
    Sheet(IoError),
}

/// A synthetic split that cannot be scored.
#[derive(Debug, thiserror::Error)]
pub enum SyntheticError {
    /// The dataset's manifest does not read or parse.
    #[error(transparent)]
    Manifest(#[from] JsonFileError),
    /// No frame in the split asked for.
    #[error("no frames in split {split:?}")]
    NoFrames {
        /// The split asked for.
        split: String,
    },
    /// A frame folder that does not load.
    #[error("frame {}", dir.display())]
    Load {
        /// The frame folder.
        dir: PathBuf,
        /// Why.
        #[source]
        source: Box<FrameLoadError>,
    },
    /// A configuration fails on a frame.
    #[error("frame {}, {row}", dir.display())]
    Run {
        /// The frame folder.
        dir: PathBuf,
        /// The configuration's key (`mode:label`).
        row: String,
        /// Why.
        #[source]
        source: Box<RunError>,
    },
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The error and its sources joined by `: `, as `tre` prints them.
    fn chain(e: &dyn std::error::Error) -> String {
        let mut out = e.to_string();
        let mut next = e.source();
        while let Some(s) = next {
            out += &format!(": {s}");
            next = s.source();
        }
        out
    }

    #[test]
    fn errors_say_what_failed_where_and_why() {
        let dir = tempfile::tempdir().expect("a temporary folder");
        let none = crate::real::find_frames(dir.path(), None).expect_err("no sequence");
        assert_eq!(
            none.to_string(),
            format!(
                "{}: no intrinsics.json in it or in its folders (see `tre eval --help` for the \
                 layout)",
                dir.path().display()
            )
        );
        let bad = dir.path().join("splits.json");
        std::fs::write(&bad, "{").expect("written");
        let e = crate::real::Splits::read(&bad).expect_err("not JSON");
        let said = chain(&e);
        assert!(
            said.starts_with(&format!("parsing {}: EOF", bad.display())),
            "{said}"
        );
        let run = BenchError::Run {
            frame: "seq/depth/1.png".to_owned(),
            row: "rgb:DE".to_owned(),
            source: Box::new(RunError::NoSensorDepth),
        };
        assert_eq!(
            chain(&run),
            "seq/depth/1.png: rgb:DE: the frame has no sensor depth to score against"
        );
    }
}
