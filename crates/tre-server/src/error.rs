//! The one mapping from every error the service can meet to an HTTP status, a stable code and a
//! message: JSON `{"error": {"code", "message"}}` over HTTP, `Error` messages on the stream.

use axum::http::{header, HeaderValue, StatusCode};
use axum::response::{IntoResponse, Response};
use serde::Serialize;
use utoipa::ToSchema;

use tre_core::geometry::GeometryError;
use tre_io::npy::NpyError;
use tre_io::{CameraSizeMismatch, DepthError, SensorSpecError};
use tre_pipeline::PipelineError;
use tre_proto::ErrorCode;

/// The HTTP status of `code` ([`ErrorCode::http_status`]).
pub(crate) fn status(code: ErrorCode) -> StatusCode {
    StatusCode::from_u16(code.http_status()).unwrap_or(StatusCode::INTERNAL_SERVER_ERROR)
}

/// An error answered to a client.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("{}: {message}", code.as_str())]
pub struct ApiError {
    /// What kind of error.
    pub code: ErrorCode,
    /// What went wrong, for a person.
    pub message: String,
}

/// Longest message an error carries, characters: messages quote what the client sent (a
/// query, a field name), and a client must not be able to make the server echo megabytes.
pub(crate) const MAX_MESSAGE_CHARS: usize = 400;

impl ApiError {
    /// An error with `code` and `message`, cut to [`MAX_MESSAGE_CHARS`].
    pub fn new(code: ErrorCode, message: impl Into<String>) -> Self {
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

impl From<PipelineError> for ApiError {
    fn from(e: PipelineError) -> Self {
        let code = match &e {
            PipelineError::EmptyImage { .. } => ErrorCode::BadImage,
            PipelineError::TooLarge { .. } => ErrorCode::TooLarge,
            PipelineError::DepthSizeMismatch { .. } => ErrorCode::BadDepth,
            PipelineError::MissingInput { .. }
            | PipelineError::ModelsRequired { .. }
            | PipelineError::BadWorkingSize { .. }
            | PipelineError::BadHypotheses { .. }
            | PipelineError::NoSensorDepth { .. } => ErrorCode::BadInput,
            PipelineError::NoSensorModel { .. } => ErrorCode::BadCamera,
            // Intrinsics that pass the camera's own checks but not once scaled to the working
            // size (a focal length of 1e308 overflows): still the camera's fault.
            PipelineError::Geometry(GeometryError::ImplausibleIntrinsics { .. }) => {
                return Self::new(ErrorCode::BadCamera, format!("camera: {e}"))
            }
            PipelineError::Geometry(
                GeometryError::BadFocalLength { .. } | GeometryError::BadPrincipalPoint { .. },
            ) => {
                return Self::new(
                    ErrorCode::BadCamera,
                    format!("camera, once scaled to the working size: {e}"),
                )
            }
            _ => ErrorCode::Internal,
        };
        Self::new(code, e.to_string())
    }
}

/// A client's `.npy` is its depth part: `too_large` when its header declares more values than
/// `--max-pixels`, else `bad_depth`.
impl From<NpyError> for ApiError {
    fn from(e: NpyError) -> Self {
        match e {
            NpyError::TooLarge { .. } => {
                Self::new(ErrorCode::TooLarge, format!("depth: {e} (--max-pixels)"))
            }
            _ => Self::new(ErrorCode::BadDepth, format!("depth: {e}")),
        }
    }
}

/// Depth values that cannot be depth (none valid, millimetres, a wrong scale).
impl From<DepthError> for ApiError {
    fn from(e: DepthError) -> Self {
        Self::new(ErrorCode::BadDepth, format!("depth: {e}"))
    }
}

/// A camera stating another image size than the frame's.
impl From<CameraSizeMismatch> for ApiError {
    fn from(e: CameraSizeMismatch) -> Self {
        Self::new(ErrorCode::BadCamera, format!("camera: {e}"))
    }
}

/// A camera's `sensor` that names no sensor (its message names the field).
impl From<SensorSpecError> for ApiError {
    fn from(e: SensorSpecError) -> Self {
        Self::new(ErrorCode::BadCamera, e.to_string())
    }
}

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
