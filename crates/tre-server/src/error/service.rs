//! The service's own refusals and failures: routes, access, the workers and their answers.

use std::time::Duration;

use axum::http::Method;
use tre_proto::ErrorCode;

/// A request the service refuses for where it went or who sent it, or fails for its own
/// reasons (the workers, a timeout, a bug, encoding the answer).
#[derive(Debug, thiserror::Error)]
pub enum ServiceError {
    /// No route at this path.
    #[error("no route {path}; see /openapi.json")]
    NoRoute {
        /// The path asked for.
        path: String,
    },
    /// A route that exists, with another method.
    #[error("{method} is not allowed on {path}; see /openapi.json")]
    MethodNotAllowed {
        /// The method used.
        method: Method,
        /// The path.
        path: String,
    },
    /// A browser origin not on `--allow-origin`.
    #[error("origin {origin:?} is not allowed (--allow-origin)")]
    OriginNotAllowed {
        /// The `Origin` header.
        origin: String,
    },
    /// No `Authorization: Bearer` header where `--api-key` wants one.
    #[error("this server wants an API key: send `Authorization: Bearer KEY`")]
    NoApiKey,
    /// A key that is not the server's.
    #[error("the API key is not this server's")]
    WrongApiKey,
    /// `GET /v1/streams/{id}/map` of no open stream with a map.
    #[error("no open stream {stream:?} keeps a map (ask for one with Hello.map)")]
    NoStreamMap {
        /// The stream id asked for.
        stream: String,
    },
    /// A stream's map before its first fused frame.
    #[error("stream {stream:?} keeps a map, but no frame has been fused into it yet")]
    EmptyStreamMap {
        /// The stream id.
        stream: String,
    },
    /// `GET /readyz` before the workers are warm, or after shutdown began.
    #[error("models loading or warming up, or shutting down")]
    NotReady,
    /// A frame before the models have loaded.
    #[error("the models are still loading")]
    Loading,
    /// A frame after shutdown began.
    #[error("the server is shutting down")]
    ShuttingDown,
    /// The queue closed under a frame.
    #[error("the workers have stopped")]
    WorkersStopped,
    /// A queued frame that did not fit back into the queue while the slots of clients that
    /// left were freed (cannot happen: fewer go back than came out).
    #[error("the queue could not keep the frame")]
    RequeueFailed,
    /// The worker dropped the frame's reply without answering.
    #[error("the worker stopped before answering")]
    WorkerStopped,
    /// A panic while running the frame (a bug).
    #[error("the frame hit a bug in the server ({panic}); the server goes on")]
    Panic {
        /// The panic's message.
        panic: String,
    },
    /// No answer within `--request-timeout-ms`.
    #[error(
        "no answer within {} ms of the body's arrival (--request-timeout-ms)",
        timeout.as_millis()
    )]
    Timeout {
        /// The timeout.
        timeout: Duration,
    },
    /// Encoding an answer's PNG failed.
    #[error("encoding PNG: {0}")]
    EncodePng(#[source] image::ImageError),
    /// Encoding an answer's `.npy` failed.
    #[error("encoding .npy: {0}")]
    EncodeNpy(#[source] std::io::Error),
}

impl ServiceError {
    /// The code of this error in the one [`ErrorCode`] table.
    pub fn code(&self) -> ErrorCode {
        match self {
            Self::NoRoute { .. } | Self::NoStreamMap { .. } | Self::EmptyStreamMap { .. } => {
                ErrorCode::NotFound
            }
            Self::MethodNotAllowed { .. } => ErrorCode::MethodNotAllowed,
            Self::OriginNotAllowed { .. } => ErrorCode::Forbidden,
            Self::NoApiKey | Self::WrongApiKey => ErrorCode::Unauthorized,
            Self::NotReady | Self::Loading | Self::ShuttingDown | Self::WorkersStopped => {
                ErrorCode::NotReady
            }
            Self::RequeueFailed => ErrorCode::Overloaded,
            Self::Timeout { .. } => ErrorCode::Timeout,
            Self::WorkerStopped | Self::Panic { .. } | Self::EncodePng(_) | Self::EncodeNpy(_) => {
                ErrorCode::Internal
            }
        }
    }
}
