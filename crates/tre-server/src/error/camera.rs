//! Refusals of a frame's camera: its JSON, its values' ranges, its intrinsics and its sensor's
//! noise coefficients.

use tre_core::geometry::GeometryError;
use tre_core::roughness::noise::CoefficientsError;
use tre_proto::ErrorCode;

/// A camera (a multipart part, the query's intrinsics, a stream message's camera) that is not
/// one.
#[derive(Debug, thiserror::Error)]
pub enum CameraError {
    /// A query camera without all four intrinsics.
    #[error("camera: give all of fx, fy, cx, cy")]
    PartialIntrinsics,
    /// A camera value out of its physical range.
    #[error("camera: {name} = {value} is outside {lo}–{hi} {unit}")]
    Range {
        /// The field.
        name: &'static str,
        /// The value given.
        value: f64,
        /// The least value.
        lo: f64,
        /// The largest value.
        hi: f64,
        /// Their unit.
        unit: &'static str,
    },
    /// A stated image side outside 1 to `--max-side`.
    #[error("camera: {name} = {side} is outside 1–{max_side} px (--max-side)")]
    Side {
        /// `width` or `height`.
        name: &'static str,
        /// The value given.
        side: usize,
        /// The limit.
        max_side: usize,
    },
    /// A camera part that is not JSON.
    #[error("camera: not valid JSON ({0})")]
    NotJson(#[source] serde_json::Error),
    /// A camera JSON that is not an object.
    #[error("camera: expected a JSON object {{fx, fy, cx, cy, ...}}")]
    NotObject,
    /// A camera JSON object that is not a camera.
    #[error(
        "camera: not valid camera JSON ({{fx, fy, cx, cy, pitch_deg?, height_m?, \
         depth_scale?, sensor?, width?, height?}}; other keys are notes): {0}"
    )]
    Fields(#[source] serde_json::Error),
    /// Intrinsics or mounting that are no camera's.
    #[error("camera: {0}")]
    Geometry(#[source] GeometryError),
    /// A depth scale that is not positive.
    #[error("{field} must be positive, got {scale}")]
    DepthScale {
        /// The words naming the field: `camera: depth_scale` (a camera part or the query),
        /// `camera.depth_scale:` (a stream message's camera).
        field: &'static str,
        /// The value given.
        scale: f64,
    },
    /// A camera message's noise coefficients that make no model.
    #[error("camera.{0}")]
    SensorCoefficients(#[source] CoefficientsError),
    /// A camera message with other than three noise coefficients.
    #[error("camera.sensor_sigma_mm: give exactly three coefficients [a, b, c], got {given}")]
    SensorCoefficientCount {
        /// How many were given.
        given: usize,
    },
}

impl CameraError {
    /// The code of this error in the one [`ErrorCode`] table: all are the camera's fault.
    pub fn code(&self) -> ErrorCode {
        match self {
            Self::PartialIntrinsics
            | Self::Range { .. }
            | Self::Side { .. }
            | Self::NotJson(_)
            | Self::NotObject
            | Self::Fields(_)
            | Self::Geometry(_)
            | Self::DepthScale { .. }
            | Self::SensorCoefficients(_)
            | Self::SensorCoefficientCount { .. } => ErrorCode::BadCamera,
        }
    }
}
