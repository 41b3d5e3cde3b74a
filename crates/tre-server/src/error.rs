//! The one mapping from every error the service can meet to an HTTP status, a stable code and a
//! message: JSON `{"error": {"code", "message"}}` over HTTP, `Error` messages on the stream.
//!
//! [`RequestError`] names every way a request is refused or fails, in groups by concern (the
//! service, its limits, the HTTP body, the options, the images, the camera, the stream: one
//! submodule each, each with its own mapping into the one [`ErrorCode`] table), and the domain
//! errors of the layers below with the context their message needs. Handlers
//! return them with `?`; `From` turns a [`RequestError`], or a domain error directly, into the
//! [`ApiError`] that is answered.

mod body;
mod camera;
mod image;
mod limits;
mod options;
mod service;
mod stream;

use axum::http::{header, HeaderValue, StatusCode};
use axum::response::{IntoResponse, Response};
use serde::Serialize;
use utoipa::ToSchema;

pub use body::BodyError;
pub use camera::CameraError;
pub use image::ImageError;
// Public through `request` with the `bench` feature only (see `lib.rs`).
#[cfg_attr(not(feature = "bench"), allow(unreachable_pub))]
pub use image::ImagePart;
pub use limits::LimitError;
pub use options::OptionError;
pub use service::ServiceError;
pub use stream::StreamError;

use tre_core::geometry::GeometryError;
use tre_io::npy::NpyError;
use tre_io::{CameraSizeMismatch, DepthError, SensorSpecError};
use tre_pipeline::PipelineError;
use tre_proto::ErrorCode;

/// The HTTP status of `code` ([`ErrorCode::http_status`]).
pub(crate) fn status(code: ErrorCode) -> StatusCode {
    StatusCode::from_u16(code.http_status()).unwrap_or(StatusCode::INTERNAL_SERVER_ERROR)
}

/// An error answered to a client: made only from a [`RequestError`] or a domain error of the
/// layers below (the `From` impls of this module), never by hand.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("{}: {message}", code.as_str())]
pub(crate) struct ApiError {
    /// What kind of error.
    pub(crate) code: ErrorCode,
    /// What went wrong, for a person.
    pub(crate) message: String,
}

/// Longest message an error carries, characters: messages quote what the client sent (a
/// query, a field name), and a client must not be able to make the server echo megabytes.
pub(crate) const MAX_MESSAGE_CHARS: usize = 400;

impl ApiError {
    /// An error with `code` and `message`, cut to [`MAX_MESSAGE_CHARS`].
    fn new(code: ErrorCode, message: impl Into<String>) -> Self {
        let message = message.into();
        let message = match super::refusals::cap(&message, MAX_MESSAGE_CHARS) {
            std::borrow::Cow::Borrowed(_) => message,
            std::borrow::Cow::Owned(cut) => cut,
        };
        Self { code, message }
    }
}

/// What a refused request was refused for, left in its response's extensions so that the
/// request-id layer logs it ([`super::access`]).
#[derive(Debug, Clone)]
pub(crate) struct Refused(pub ApiError);

/// Why the service refuses or fails a request: a group of errors by concern, each with its own
/// mapping into the one [`ErrorCode`] table, or a domain error of the layers below with the
/// context the client needs. Its message is the answer's; [`RequestError::code`] chooses the
/// code (and so the HTTP status).
#[derive(Debug, thiserror::Error)]
pub enum RequestError {
    /// Routes, access, the workers and the answer.
    #[error(transparent)]
    Service(#[from] ServiceError),
    /// The service's limits.
    #[error(transparent)]
    Limit(#[from] LimitError),
    /// An HTTP request's body and query.
    #[error(transparent)]
    Body(#[from] BodyError),
    /// A frame's options, from the query or the Hello.
    #[error(transparent)]
    Options(#[from] OptionError),
    /// The images of a frame.
    #[error(transparent)]
    Image(#[from] ImageError),
    /// A frame's camera.
    #[error(transparent)]
    Camera(#[from] CameraError),
    /// The stream's messages.
    #[error(transparent)]
    Stream(#[from] StreamError),

    // A Hello's map settings (checked in `map.rs`, beside the map they make).
    /// A map cell outside 1 mm to 1 m.
    #[error("hello.map.cell_m: {cell_m} is outside 0.001–1 m")]
    MapCellSize {
        /// The size given, metres.
        cell_m: f64,
    },
    /// A map of more than 1000 cells a side.
    #[error("hello.map.side: {side} is more than 1000 cells")]
    MapSide {
        /// The cells given.
        side: usize,
    },
    /// A map update rate that is negative or not finite.
    #[error("hello.map.send_hz: {send_hz} is not a rate")]
    MapSendRate {
        /// The rate given.
        send_hz: f64,
    },
    /// A map gravity direction that is not 3 finite values, not all 0.
    #[error("hello.map.gravity: expected 3 finite values, not all 0, got {gravity:?}")]
    MapGravity {
        /// The values given.
        gravity: Vec<f64>,
    },

    // The domain errors of the layers below.
    /// The frame does not fit the pipeline (or the pipeline failed). Boxed: the largest error
    /// of the layers below.
    #[error("{}", pipeline_message(.0))]
    Pipeline(#[source] Box<PipelineError>),
    /// A depth `.npy` that does not read.
    #[error("depth: {}{}", .0, npy_option(.0))]
    Npy(#[from] NpyError),
    /// Depth values that cannot be depth in metres.
    #[error("depth: {0}")]
    Depth(#[from] DepthError),
    /// A camera stating another image size than the frame's.
    #[error("camera: {0}")]
    CameraSize(#[from] CameraSizeMismatch),
    /// A camera's `sensor` that names no sensor (its message names the field).
    #[error(transparent)]
    SensorSpec(#[from] SensorSpecError),
}

impl RequestError {
    /// The code of this error, and so its HTTP status ([`ErrorCode::http_status`]): each
    /// group's own mapping, and the domain errors'.
    pub fn code(&self) -> ErrorCode {
        match self {
            Self::Service(e) => e.code(),
            Self::Limit(e) => e.code(),
            Self::Body(e) => e.code(),
            Self::Options(e) => e.code(),
            Self::Image(e) => e.code(),
            Self::Camera(e) => e.code(),
            Self::Stream(e) => e.code(),
            Self::MapCellSize { .. }
            | Self::MapSide { .. }
            | Self::MapSendRate { .. }
            | Self::MapGravity { .. } => ErrorCode::BadRequest,
            Self::Pipeline(e) => pipeline_code(e),
            // A client's `.npy` is its depth part: `too_large` when its header declares more
            // values than `--max-pixels`.
            Self::Npy(NpyError::TooLarge { .. }) => ErrorCode::TooLarge,
            Self::Npy(_) | Self::Depth(_) => ErrorCode::BadDepth,
            Self::CameraSize(_) | Self::SensorSpec(_) => ErrorCode::BadCamera,
        }
    }
}

/// The code of a pipeline error: the frame's fault (its images, its inputs for the mode, its
/// camera) or the service's.
fn pipeline_code(e: &PipelineError) -> ErrorCode {
    match e {
        PipelineError::EmptyImage { .. } => ErrorCode::BadImage,
        PipelineError::TooLarge { .. } => ErrorCode::TooLarge,
        PipelineError::DepthSizeMismatch { .. } => ErrorCode::BadDepth,
        PipelineError::MissingInput { .. }
        | PipelineError::ModelsRequired { .. }
        | PipelineError::BadWorkingSize { .. }
        | PipelineError::BadHypotheses { .. }
        | PipelineError::NoSensorDepth { .. }
        | PipelineError::UnusedDepth => ErrorCode::BadInput,
        PipelineError::NoSensorModel { .. } => ErrorCode::BadCamera,
        // Intrinsics that pass the camera's own checks but not once scaled to the working
        // size (a focal length of 1e308 overflows): still the camera's fault.
        PipelineError::Geometry(
            GeometryError::ImplausibleIntrinsics { .. }
            | GeometryError::BadFocalLength { .. }
            | GeometryError::BadPrincipalPoint { .. },
        ) => ErrorCode::BadCamera,
        PipelineError::Geometry(_)
        | PipelineError::Calibration { .. }
        | PipelineError::Model(_)
        | PipelineError::LoadModels { .. }
        | PipelineError::Threads(_) => ErrorCode::Internal,
    }
}

/// The option behind a client's `.npy` error, if one is: `--max-pixels` for a header that
/// declares too many values.
fn npy_option(e: &NpyError) -> &'static str {
    match e {
        NpyError::TooLarge { .. } => " (--max-pixels)",
        _ => "",
    }
}

/// The message of a pipeline error: its own, with where a camera error comes from.
fn pipeline_message(e: &PipelineError) -> String {
    match e {
        PipelineError::Geometry(GeometryError::ImplausibleIntrinsics { .. }) => {
            format!("camera: {e}")
        }
        PipelineError::Geometry(
            GeometryError::BadFocalLength { .. } | GeometryError::BadPrincipalPoint { .. },
        ) => format!("camera, once scaled to the working size: {e}"),
        _ => e.to_string(),
    }
}

impl From<PipelineError> for RequestError {
    fn from(e: PipelineError) -> Self {
        Self::Pipeline(Box::new(e))
    }
}

impl From<RequestError> for ApiError {
    fn from(e: RequestError) -> Self {
        Self::new(e.code(), e.to_string())
    }
}

/// `From` a domain error of the layers below for [`ApiError`], through [`RequestError`].
macro_rules! answered_as_request_errors {
    ($($domain:ty),* $(,)?) => {$(
        impl From<$domain> for ApiError {
            fn from(e: $domain) -> Self {
                RequestError::from(e).into()
            }
        }
    )*};
}

answered_as_request_errors!(
    ServiceError,
    LimitError,
    BodyError,
    OptionError,
    ImageError,
    CameraError,
    StreamError,
    PipelineError,
    NpyError,
    DepthError,
    CameraSizeMismatch,
    SensorSpecError,
);

/// Seconds a refused client should wait before retrying.
pub(crate) const RETRY_AFTER_S: u32 = 1;

/// An error answer over HTTP: `{"error": {"code", "message"}}`.
#[derive(Serialize, ToSchema)]
#[schema(as = Error)]
pub(crate) struct Body<'a> {
    #[schema(inline)]
    error: Inner<'a>,
}

/// What went wrong: a stable code and a message for a person.
#[derive(Serialize, ToSchema)]
struct Inner<'a> {
    #[schema(inline)]
    code: ErrorCode,
    message: &'a str,
}

impl IntoResponse for ApiError {
    fn into_response(self) -> Response {
        let body = Body {
            error: Inner {
                code: self.code,
                message: &self.message,
            },
        };
        let json = serde_json::to_vec(&body).unwrap_or_else(|_| b"{}".to_vec());
        let mut resp = (
            status(self.code),
            [(header::CONTENT_TYPE, "application/json")],
            json,
        )
            .into_response();
        if self.code.retryable() {
            resp.headers_mut()
                .insert(header::RETRY_AFTER, HeaderValue::from(RETRY_AFTER_S));
        }
        if self.code == ErrorCode::Unauthorized {
            resp.headers_mut().insert(
                header::WWW_AUTHENTICATE,
                HeaderValue::from_static("Bearer realm=\"tre\""),
            );
        }
        resp.extensions_mut().insert(Refused(self));
        resp
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use strum::IntoEnumIterator;

    #[test]
    fn every_code_has_a_distinct_name_and_an_error_status() {
        let mut names: Vec<_> = ErrorCode::iter().map(ErrorCode::as_str).collect();
        names.sort_unstable();
        names.dedup();
        assert_eq!(names.len(), ErrorCode::iter().count());
        for code in ErrorCode::iter() {
            let json = serde_json::to_value(code).expect("serialises");
            assert_eq!(
                json,
                serde_json::json!(code.as_str()),
                "JSON body and wire name"
            );
            let status = status(code).as_u16();
            assert!((400..600).contains(&status), "{code:?} → {status}");
            assert_eq!(code.retryable(), status == 429 || status == 503);
        }
    }

    #[test]
    fn io_errors_map_to_the_part_they_come_from() {
        let e = ApiError::from(NpyError::TooLarge {
            shape: vec![3000, 3000],
            limit: 100,
        });
        assert_eq!(e.code, ErrorCode::TooLarge);
        assert!(e.message.starts_with("depth: ") && e.message.ends_with("(--max-pixels)"));
        let e = ApiError::from(NpyError::FortranOrder);
        assert_eq!(e.code, ErrorCode::BadDepth);
        let e = ApiError::from(DepthError::TooFar { median_m: 1500.0 });
        assert_eq!(
            (e.code, e.message.contains("millimetres")),
            (ErrorCode::BadDepth, true)
        );
        let e = ApiError::from(CameraSizeMismatch {
            camera_width: Some(640),
            camera_height: Some(480),
            frame_width: 320,
            frame_height: 240,
        });
        assert_eq!(e.code, ErrorCode::BadCamera);
        assert!(
            e.message.starts_with("camera: ") && e.message.contains("640×480"),
            "{e}"
        );
        let e = ApiError::from(SensorSpecError::NotASensor { keys: None });
        assert_eq!(e.code, ErrorCode::BadCamera);
        assert!(e.message.starts_with("sensor: "), "{e}");
    }

    #[test]
    fn messages_are_capped() {
        let e = ApiError::new(ErrorCode::BadRequest, "x".repeat(100_000));
        assert_eq!(e.message.chars().count(), MAX_MESSAGE_CHARS + 1);
        let short = ApiError::new(ErrorCode::BadRequest, "short");
        assert_eq!(short.message, "short");
    }
}
