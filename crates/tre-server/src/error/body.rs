//! Refusals of an HTTP request's body and query as such: reading it, its media type, its
//! multipart parts.

use axum::extract::multipart::{MultipartError, MultipartRejection};
use axum::extract::rejection::QueryRejection;
use tre_proto::ErrorCode;

/// An HTTP body or query that does not read as a frame request.
#[derive(Debug, thiserror::Error)]
pub enum BodyError {
    /// The body could not be read.
    #[error("reading the body: {0}")]
    ReadBody(#[source] axum::Error),
    /// A body that is neither an image nor multipart.
    #[error("Content-Type {essence:?}: send image/png, image/jpeg or multipart/form-data")]
    ContentType {
        /// The media type sent, lowercase, without parameters.
        essence: String,
    },
    /// A query the parameters do not read.
    #[error("query {query:?}: {}", rejection.body_text())]
    Query {
        /// The query string.
        query: String,
        /// Why it does not read.
        #[source]
        rejection: QueryRejection,
    },
    /// A multipart `Content-Type` that is not a header value.
    #[error("multipart: {0}")]
    MultipartHeader(#[source] axum::http::Error),
    /// A multipart body without a boundary.
    #[error("multipart: {}", .0.body_text())]
    MultipartBoundary(#[source] MultipartRejection),
    /// A multipart body that does not parse.
    #[error("multipart: {}", .0.body_text())]
    Multipart(#[source] MultipartError),
    /// A multipart part that does not read.
    #[error("multipart field {name:?}: {}", source.body_text())]
    MultipartField {
        /// The part's name.
        name: String,
        /// Why it does not read.
        source: MultipartError,
    },
    /// A multipart part other than `rgb`, `depth`, `camera`.
    #[error("multipart: unknown field {name:?} (rgb, depth, camera)")]
    UnknownPart {
        /// Its name.
        name: String,
    },
    /// Multipart without an image.
    #[error("multipart: give an `rgb` part, a `depth` part or both")]
    NoImagePart,
    /// A multipart part given twice.
    #[error("multipart: the {name:?} part is given twice; send each part once")]
    PartTwice {
        /// Its name.
        name: String,
    },
    /// A camera in the query and in the multipart body.
    #[error("the camera is given both in the query and as a multipart part; give it once")]
    CameraTwice,
}

impl BodyError {
    /// The code of this error in the one [`ErrorCode`] table.
    pub fn code(&self) -> ErrorCode {
        match self {
            Self::ContentType { .. } => ErrorCode::UnsupportedMedia,
            Self::ReadBody(_)
            | Self::Query { .. }
            | Self::MultipartHeader(_)
            | Self::MultipartBoundary(_)
            | Self::Multipart(_)
            | Self::MultipartField { .. }
            | Self::UnknownPart { .. }
            | Self::NoImagePart
            | Self::PartTwice { .. }
            | Self::CameraTwice => ErrorCode::BadRequest,
        }
    }
}
