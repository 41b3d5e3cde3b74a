//! One frame through all stages of the paper's Fig. 5: resize to the working size, depth
//! (`depth.rs`), back-projection, normals (`normals.rs`: LS or DSAC, optional refiner),
//! centroids and Eq. 1 (`centroid.rs`), then slope, traversability and the maps back at the
//! frame's size (`run.rs`). The learned stages run through [`tre_model::Models`]; everything
//! else is the native geometry of [`tre_core::geometry`].
//!
//! ```no_run
//! # fn main() -> Result<(), Box<dyn std::error::Error>> {
//! use tre_model::{Models, SessionConfig};
//! use tre_pipeline::{FrameInput, Pipeline, PipelineConfig};
//! let models = Models::load("models".as_ref(), &SessionConfig::default())?;
//! let mut pipeline = Pipeline::new(Some(models));
//! let rgb = image::open("frame.png")?.to_rgb8();
//! let frame = FrameInput { rgb: Some(rgb), ..FrameInput::default() };
//! let out = pipeline.run(&frame, &PipelineConfig::default())?;
//! println!("{:?}", out.timings);
//! // Done with this frame's maps: the next frames write into their buffers.
//! pipeline.recycle(out);
//! # Ok(())
//! # }
//! ```

mod calibration;
mod centroid;
mod check;
#[cfg(feature = "cli")]
mod cli;
mod config;
mod depth;
mod frame;
mod gravity;
mod load;
mod normals;
mod plausible;
pub mod resize;
mod run;
mod spares;
mod summary;
mod tensors;
mod timings;

pub use calibration::{models_key, read_calibration, stale_calibration, CalibrationProblem};
pub use check::check_input;
#[cfg(feature = "cli")]
pub use cli::StageArgs;
pub use config::{
    check_dsac_hypotheses, CentroidMethod, GeometricMethod, Method, Mode, NormalsMethod,
    PipelineConfig, Traversability, DEFAULT_DSAC_HYPOTHESES, DEFAULT_MAX_INPUT_PIXELS,
    MAX_DSAC_HYPOTHESES, MAX_WORKING_SIDE, SPEC_CLEANED_TABLE,
};
pub use depth::{prior_depth, MAX_PRIOR_DEPTH_M};
pub use frame::{FrameInput, FrameOutput, SensorMaps, DEFAULT_HFOV_DEG};
pub use gravity::{Assumption, Gravity, GravityFigures, GravityUnknown};
pub use plausible::{Implausible, MAX_GROUND_BELOW_M, MAX_MEDIAN_DEPTH_M};
pub use run::{Pipeline, DEFAULT_WORKING_SIZE};
pub use summary::MOSTLY_UNKNOWN_SHARE;
pub use timings::StageTimings;

use tre_core::geometry::GeometryError;
use tre_core::roughness::noise::SensorPreset;
use tre_model::{ModelError, ThreadsError};

/// Errors of the pipeline layer: bad frames, bad settings, and failures of the stages.
#[derive(Debug, thiserror::Error)]
pub enum PipelineError {
    /// An image or depth map with no pixels.
    #[error("the {what} is empty ({}×{})", size.0, size.1)]
    EmptyImage {
        /// `rgb` or `depth`.
        what: &'static str,
        /// Its `(width, height)`.
        size: (usize, usize),
    },
    /// A frame larger than the configured limit.
    #[error("the frame is {}×{} = {} pixels, more than the limit of {max_pixels}", size.0, size.1, size.0 * size.1)]
    TooLarge {
        /// `(width, height)`.
        size: (usize, usize),
        /// The limit, pixels.
        max_pixels: usize,
    },
    /// A depth map whose size differs from the RGB frame's.
    #[error("the depth map is {}×{} but the RGB frame is {}×{}; they must be registered and the same size", depth.0, depth.1, rgb.0, rgb.1)]
    DepthSizeMismatch {
        /// RGB `(width, height)`.
        rgb: (usize, usize),
        /// Depth `(width, height)`.
        depth: (usize, usize),
    },
    /// An input the mode needs is absent.
    #[error("{mode} needs {input}, which the frame does not have")]
    MissingInput {
        /// The mode or method, in words.
        mode: &'static str,
        /// `rgb` or `depth`.
        input: &'static str,
    },
    /// The configuration runs networks that are not loaded.
    #[error("{label} runs {}, but {}", networks.join(", "), if *loaded { "the manifest does not list them" } else { "no models are loaded (give a models folder)" })]
    ModelsRequired {
        /// The configuration's label (e.g. `DE+DSAC+NR+ESR`).
        label: String,
        /// The networks it needs, by manifest name.
        networks: Vec<&'static str>,
        /// Whether models are loaded at all.
        loaded: bool,
    },
    /// A working size that is zero, too large, or not a multiple of the stride.
    #[error("working size {}×{} must be positive, at most {MAX_WORKING_SIDE} per side{}", size.0, size.1, stride.map_or(" (without networks, the geometric mode works at the frame's own size unless one is set)".to_string(), |s| format!(" and a multiple of the models' stride {s}")))]
    BadWorkingSize {
        /// `(width, height)`.
        size: (usize, usize),
        /// The stride the networks need, if any run.
        stride: Option<usize>,
    },
    /// A number of DSAC hypotheses outside 1 to [`MAX_DSAC_HYPOTHESES`].
    #[error("DSAC hypotheses per pixel must be 1 to {MAX_DSAC_HYPOTHESES}, not {got}")]
    BadHypotheses {
        /// The number asked for.
        got: u32,
    },
    /// Depth given with the `rgb` mode, which predicts its own depth and would drop it: refused
    /// rather than ignored ([`PipelineConfig::check_depth_used`]).
    #[error(
        "the rgb mode predicts depth from the RGB frame alone, so the depth given would be \
         ignored; use mode rgbd (RGB with this depth) or geometric (the depth alone), or send no \
         depth"
    )]
    UnusedDepth,
    /// Uncertainty or three-state maps asked for without sensor depth.
    #[error(
        "the uncertainty and three-state maps need sensor depth (modes rgbd and geometric) or the \
         mode's calibration table (models/uncertainty.json, written by `tre calibrate`), which the \
         loaded models lack for the {mode} mode; its depth comes from the depth net, whose error \
         no sensor model describes"
    )]
    NoSensorDepth {
        /// The mode or method, in words.
        mode: &'static str,
    },
    /// Uncertainty or three-state maps asked for without a sensor noise model.
    #[error(
        "the uncertainty and three-state maps need the depth sensor's noise model: name it as \
         the camera's \"sensor\" (one of {}) or give {{\"sigma_mm\": [a, b, c]}}{}",
        SensorPreset::names(),
        described.as_ref().map_or(String::new(), |d| {
            format!(" (the camera's sensor {d:?} names no preset)")
        })
    )]
    NoSensorModel {
        /// The camera's free-text sensor, which names no preset, if it gave one.
        described: Option<String>,
    },
    /// A calibration file (`uncertainty.json` beside the models) that does not read.
    // The reason is in the message, not a `source`: a report that prints the chain would say
    // it twice.
    #[error("{}: {reason}", path.display())]
    Calibration {
        /// The file.
        path: std::path::PathBuf,
        /// What is wrong.
        reason: CalibrationProblem,
    },
    /// Bad intrinsics or mounting, or geometry inputs that do not fit.
    #[error(transparent)]
    Geometry(#[from] GeometryError),
    /// A learned stage failed, or no models folder was found.
    #[error(transparent)]
    Model(#[from] ModelError),
    /// The models of a folder could not be loaded.
    #[error("loading models from {}", dir.display())]
    LoadModels {
        /// The models folder.
        dir: std::path::PathBuf,
        /// Why (boxed: a [`ModelError`] beside a path would make every pipeline error large).
        #[source]
        source: Box<ModelError>,
    },
    /// ONNX Runtime threads the cores cannot use.
    #[error(transparent)]
    Threads(#[from] ThreadsError),
}
