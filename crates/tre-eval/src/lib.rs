//! Evaluation of tre, as a library: the real-frame benchmark ([`real`]: every mode on real RGB-D
//! frames scored against annotation spec v1 on the same sensor depth, its report, safety
//! figures, splits and contact sheets) and the synthetic split ([`synthetic`]: a `tre synth`
//! dataset's scores, and the paper's Tables II, IV and V in [`tables`]). `tre eval` and `tre
//! calibrate` parse arguments, call these and print.

pub mod calibrate;
#[cfg(feature = "cli")]
mod cli;
pub mod error;
pub mod real;
pub mod synthetic;
pub mod tables;

#[cfg(feature = "cli")]
pub use cli::{CalibrateArgs, CalibrateError, EvalArgs, Fitted, OneModeError};
pub use error::{
    BenchError, FrameLoadError, FramesError, JsonFileError, RunError, SplitsError, SyntheticError,
};
