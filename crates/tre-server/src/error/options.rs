//! Refusals of a frame's options, whichever transport gave them: the HTTP query's parameters
//! and the stream's Hello name the same options, and share their errors; `field` says which
//! one the client wrote.

use tre_core::kinds::{ChoiceError, TraversabilityError};
use tre_core::roughness::noise::SensorPreset;
use tre_pipeline::PipelineError;
use tre_proto::ErrorCode;

use crate::options::OutputMap;

/// An option of a frame request that is not one: out of its range or naming nothing.
#[derive(Debug, thiserror::Error)]
pub enum OptionError {
    /// A choice parameter outside its enum (tre-core's
    /// [`parse_choice`](tre_core::kinds::parse_choice) message, which names the field).
    #[error(transparent)]
    Choice(#[from] ChoiceError),
    /// An enum field of the stream's protocol with a value the protocol does not define.
    #[error("{field}: unknown value {value}")]
    UnknownValue {
        /// The field, `hello.mode` say.
        field: &'static str,
        /// The value sent.
        value: i32,
    },
    /// `dsac_hypotheses` out of its range.
    #[error("{field}: {source}")]
    DsacHypotheses {
        /// The field: `dsac_hypotheses` (query), `hello.dsac_hypotheses` (stream).
        field: &'static str,
        /// The pipeline's check.
        source: Box<PipelineError>,
    },
    /// A colour scale that is not positive.
    #[error("{field}: must be positive, got {value}")]
    PreviewMax {
        /// The field: `preview_max_cm` (query), `hello.preview_max_m` (stream).
        field: &'static str,
        /// The value given, in the field's unit.
        value: f64,
    },
    /// Traversability thresholds out of their range (the error names its field).
    #[error("{prefix}{source}")]
    Traversability {
        /// What comes before the field's name: nothing (query), `hello.` (stream).
        prefix: &'static str,
        /// The range check.
        source: TraversabilityError,
    },
    /// A `sensor` that does not read: tre-core's `SensorNoise` parsing message (query), or
    /// the error of the camera's sensor (stream).
    #[error("{field}: {source}")]
    Sensor {
        /// The field: `sensor` (query), `hello.sensor` (stream).
        field: &'static str,
        /// Why it does not read.
        source: Box<dyn std::error::Error + Send + Sync>,
    },
    /// A Hello's `sensor` that describes a sensor without naming a noise model.
    #[error(
        "hello.sensor: {description:?} names no noise model; one of {}",
        SensorPreset::names()
    )]
    SensorDescription {
        /// The text given.
        description: String,
    },
    /// An `outputs` entry that names no map.
    #[error("outputs: unknown map {name:?} ({})", OutputMap::all_names())]
    UnknownOutput {
        /// The name given.
        name: String,
    },
    /// A Hello that asks for a map without a noise model.
    #[error(
        "hello.map: the map's height variance needs a sensor noise model: the camera's sensor \
         or hello.sensor"
    )]
    MapWithoutSensor,
}

impl OptionError {
    /// The code of this error in the one [`ErrorCode`] table: all are the request's fault.
    pub fn code(&self) -> ErrorCode {
        match self {
            Self::Choice(_)
            | Self::UnknownValue { .. }
            | Self::DsacHypotheses { .. }
            | Self::PreviewMax { .. }
            | Self::Traversability { .. }
            | Self::Sensor { .. }
            | Self::SensorDescription { .. }
            | Self::UnknownOutput { .. }
            | Self::MapWithoutSensor => ErrorCode::BadRequest,
        }
    }
}
