//! The one mapping from every error the service can meet to an HTTP status, a stable code and a
//! message: JSON `{"error": {"code", "message"}}` over HTTP, `Error` messages on the stream.
//!
//! [`RequestError`] names every way a request is refused or fails (the service's own checks and
//! limits, and the domain errors of the layers below with the context their message needs);
//! [`RequestError::code`] chooses the [`ErrorCode`] of each, and so its HTTP status. Handlers
//! return them with `?`; `From` turns a [`RequestError`], or a domain error directly, into the
//! [`ApiError`] that is answered.

use std::time::Duration;

use axum::extract::multipart::{MultipartError, MultipartRejection};
use axum::extract::rejection::QueryRejection;
use axum::extract::ws::rejection::WebSocketUpgradeRejection;
use axum::http::{header, HeaderValue, Method, StatusCode};
use axum::response::{IntoResponse, Response};
use serde::Serialize;
use utoipa::ToSchema;

use super::options::OutputMap;
use super::pace::TooSlow;
use tre_core::geometry::GeometryError;
use tre_core::kinds::TraversabilityError;
use tre_core::map::MapError;
use tre_core::roughness::noise::{CoefficientsError, SensorPreset};
use tre_io::npy::NpyError;
use tre_io::{CameraSizeMismatch, DepthError, JpegError, SensorSpecError};
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

/// Which image of a request an error is about.
#[derive(Debug, Clone, Copy, PartialEq, Eq, strum::Display)]
#[strum(serialize_all = "lowercase")]
pub enum ImagePart {
    /// The colour frame (the HTTP part `rgb`, the stream frame's `image`).
    Rgb,
    /// The depth frame (the HTTP part `depth`, the stream frame's `depth`).
    Depth,
}

/// Why the service refuses or fails a request: its own checks and limits, and the domain
/// errors of the layers below, each with the context the client needs. Its message is the
/// answer's; [`RequestError::code`] chooses the code (and so the HTTP status) of every variant.
#[derive(Debug, thiserror::Error)]
pub enum RequestError {
    // Routes, access and the service's own limits.
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
    /// `--max-connections` connections are open.
    #[error(
        "the server holds its limit of {max_open} open connections (--max-connections); retry \
         later"
    )]
    TooManyConnections {
        /// The limit.
        max_open: usize,
    },
    /// `--max-concurrent` requests are being handled.
    #[error("more than {max_concurrent} requests at once (--max-concurrent); retry later")]
    TooManyRequests {
        /// The limit.
        max_concurrent: usize,
    },
    /// `--max-streams` streams are open.
    #[error("{max_streams} streams are open, the limit (--max-streams); retry later")]
    StreamsFull {
        /// The limit.
        max_streams: usize,
    },
    /// `--max-connections` streams wait for their first message.
    #[error(
        "{max_connections} streams wait for their first message, the limit \
         (--max-connections); retry later"
    )]
    StreamsWaiting {
        /// The limit.
        max_connections: usize,
    },
    /// The stream's route asked for without a WebSocket upgrade.
    #[error("/v1/stream is a WebSocket: {}", .0.body_text())]
    NotAWebSocket(#[source] WebSocketUpgradeRejection),
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

    // The workers and their queue.
    /// `GET /readyz` before the workers are warm, or after shutdown began.
    #[error("models loading or warming up, or shutting down")]
    NotReady,
    /// A frame before the models have loaded.
    #[error("the models are still loading")]
    Loading,
    /// A frame after shutdown began.
    #[error("the server is shutting down")]
    ShuttingDown,
    /// The queue is full.
    #[error("all {workers} workers are busy and {queued} frames are queued; retry later")]
    QueueFull {
        /// Worker threads.
        workers: usize,
        /// Frames the queue holds.
        queued: usize,
    },
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

    // An HTTP request's body and query.
    /// The body did not arrive within `--body-timeout-ms`.
    #[error(
        "the body did not arrive within {} ms (--body-timeout-ms)",
        timeout.as_millis()
    )]
    BodyTimeout {
        /// The timeout.
        timeout: Duration,
    },
    /// The body fell below `--min-body-rate` over a window.
    #[error(
        "the body arrived at {rate:.0} bytes/s over {secs:.1} s, below the minimum of \
         {min_bytes_per_s} bytes/s (--min-body-rate)"
    )]
    BodyTooSlow {
        /// Its rate over the window, bytes a second.
        rate: f64,
        /// The window, seconds.
        secs: f64,
        /// The least rate, bytes a second.
        min_bytes_per_s: u64,
    },
    /// A body over `--max-body-bytes`.
    #[error(
        "the body is larger than the limit of {} (--max-body-bytes)",
        tre_io::units::format_size(*limit, "B")
    )]
    BodyTooLarge {
        /// The limit, bytes.
        limit: usize,
    },
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
    /// A choice parameter outside its enum (tre-core's
    /// [`parse_choice`](tre_core::kinds::parse_choice) message, which names the field).
    #[error("{0}")]
    Choice(String),
    /// `dsac_hypotheses` out of its range.
    #[error("dsac_hypotheses: {0}")]
    DsacHypotheses(#[source] Box<PipelineError>),
    /// A colour scale that is not positive.
    #[error("preview_max_cm: must be positive, got {cm}")]
    PreviewMax {
        /// The value given.
        cm: f64,
    },
    /// Traversability thresholds out of their range.
    #[error(transparent)]
    Traversability(TraversabilityError),
    /// A `sensor` that names no noise model (tre-core's `SensorNoise` parsing message).
    #[error("sensor: {0}")]
    Sensor(String),
    /// An `outputs` entry that names no map.
    #[error("outputs: unknown map {name:?} ({})", OutputMap::all_names())]
    UnknownOutput {
        /// The name given.
        name: String,
    },
    /// A query camera without all four intrinsics.
    #[error("camera: give all of fx, fy, cx, cy")]
    PartialIntrinsics,

    // The images of a frame.
    /// An empty part.
    #[error("{part}: empty")]
    EmptyImage {
        /// Which.
        part: ImagePart,
    },
    /// Bytes that are neither PNG nor JPEG.
    #[error("{part}: not a PNG or JPEG image")]
    NotAnImage {
        /// Which.
        part: ImagePart,
    },
    /// A PNG (or a JPEG's header) that does not decode.
    #[error("{part}: {source}")]
    Undecodable {
        /// Which.
        part: ImagePart,
        /// The decoder's error.
        source: image::ImageError,
    },
    /// A JPEG that is not whole and valid.
    #[error("{part}: {source}")]
    Jpeg {
        /// Which.
        part: ImagePart,
        /// The decoder's error.
        source: JpegError,
    },
    /// An image without pixels.
    #[error("{part}: the image is {}×{}, it has no pixels", size.0, size.1)]
    NoPixels {
        /// Which.
        part: ImagePart,
        /// Its `(width, height)`.
        size: (usize, usize),
    },
    /// An image side over `--max-side`.
    #[error(
        "{part}: the image is {}×{}, a side longer than the limit of {max_side} pixels \
         (--max-side)",
        size.0,
        size.1
    )]
    SideTooLong {
        /// Which.
        part: ImagePart,
        /// Its `(width, height)`.
        size: (usize, usize),
        /// The limit, pixels.
        max_side: usize,
    },
    /// An image over `--max-pixels`.
    #[error(
        "{part}: the image is {}×{} = {} pixels, more than the limit of {max_pixels} ({} \
         pixels, --max-pixels)",
        size.0,
        size.1,
        (size.0 as u64).saturating_mul(size.1 as u64),
        tre_io::units::format_size(*max_pixels, "")
    )]
    TooManyPixels {
        /// Which.
        part: ImagePart,
        /// Its `(width, height)`.
        size: (usize, usize),
        /// The limit, pixels.
        max_pixels: usize,
    },
    /// An image longer than `--max-aspect` times its width.
    #[error(
        "{part}: the image is {}×{}, its longer side more than {max_aspect} times the shorter \
         (--max-aspect)",
        size.0,
        size.1
    )]
    TooNarrow {
        /// Which.
        part: ImagePart,
        /// Its `(width, height)`.
        size: (usize, usize),
        /// The limit.
        max_aspect: usize,
    },
    /// A 16-bit grey image sent as the colour frame.
    #[error(
        "rgb: {why}: the multipart part `depth` over HTTP (a `camera` part gives its \
         depth_scale), the frame's `depth` field on the stream"
    )]
    DepthAsRgb {
        /// tre-io's words for it ([`tre_io::not_rgb`]).
        why: &'static str,
    },
    /// A depth part that is no image (or a broken one): the image's error, and what depth may
    /// be.
    #[error("{0}; depth must be a 16-bit grey PNG or a float .npy")]
    NotDepth(#[source] Box<RequestError>),
    /// A depth image of another colour type than 16-bit grey.
    #[error("depth: must be a 16-bit grey PNG or a float .npy, got {color:?}")]
    DepthColour {
        /// Its colour type.
        color: image::ColorType,
    },
    /// A frame without an image or depth.
    #[error("the frame has neither an image nor depth")]
    NoInput,

    // A frame's camera.
    /// A camera value out of its physical range.
    #[error("camera: {name} = {value} is outside {lo}–{hi} {unit}")]
    CameraRange {
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
    CameraSide {
        /// `width` or `height`.
        name: &'static str,
        /// The value given.
        side: usize,
        /// The limit.
        max_side: usize,
    },
    /// A camera part that is not JSON.
    #[error("camera: not valid JSON ({0})")]
    CameraNotJson(#[source] serde_json::Error),
    /// A camera JSON that is not an object.
    #[error("camera: expected a JSON object {{fx, fy, cx, cy, ...}}")]
    CameraNotObject,
    /// A camera JSON object that is not a camera.
    #[error(
        "camera: not valid camera JSON ({{fx, fy, cx, cy, pitch_deg?, height_m?, \
         depth_scale?, sensor?, width?, height?}}; other keys are notes): {0}"
    )]
    CameraFields(#[source] serde_json::Error),
    /// Intrinsics or mounting that are no camera's.
    #[error("camera: {0}")]
    Camera(#[source] GeometryError),
    /// A depth scale that is not positive.
    #[error("camera: depth_scale must be positive, got {scale}")]
    DepthScale {
        /// The value given.
        scale: f64,
    },

    // The stream's messages.
    /// A binary message that is not a `ClientMessage`.
    #[error("message: not a roughness.v1.ClientMessage: {0}")]
    NotAMessage(#[source] prost::DecodeError),
    /// A `ClientMessage` with neither a Hello nor a frame.
    #[error("message: empty ClientMessage (neither hello nor frame)")]
    EmptyMessage,
    /// A text message.
    #[error("text messages are not part of the protocol; send binary roughness.v1.ClientMessage")]
    TextMessage,
    /// A message over `--ws-max-message-bytes`.
    #[error("message of {bytes} bytes, more than the limit of {limit}")]
    MessageTooLarge {
        /// Its size.
        bytes: usize,
        /// The limit.
        limit: usize,
    },
    /// A message that arrived below `--min-body-rate` over a window.
    #[error(
        "a message arrived at {:.0} bytes/s over {secs:.1} s, below the minimum of \
         {min_bytes_per_s} bytes/s (--min-body-rate); closed with 1008",
        *bytes as f64 / secs.max(1e-9)
    )]
    MessageTooSlow {
        /// Its bytes over the window.
        bytes: u64,
        /// The window's length, seconds.
        secs: f64,
        /// The least rate, bytes a second.
        min_bytes_per_s: u64,
    },
    /// A frame before the stream's Hello.
    #[error("send a Hello before the first frame")]
    FrameBeforeHello,
    /// An enum field with a value the protocol does not define.
    #[error("{field}: unknown value {value}")]
    UnknownValue {
        /// The field, `hello.mode` say.
        field: &'static str,
        /// The value sent.
        value: i32,
    },
    /// `hello.dsac_hypotheses` out of its range.
    #[error("hello.dsac_hypotheses: {0}")]
    HelloDsacHypotheses(#[source] Box<PipelineError>),
    /// `hello.preview_max_m` not positive.
    #[error("hello.preview_max_m: must be positive, got {m}")]
    HelloPreviewMax {
        /// The value given.
        m: f64,
    },
    /// A Hello's `sensor` that describes a sensor without naming a noise model.
    #[error(
        "hello.sensor: {description:?} names no noise model; one of {}",
        SensorPreset::names()
    )]
    HelloSensorDescription {
        /// The text given.
        description: String,
    },
    /// A Hello's `sensor` that does not read (the camera's sensor's error).
    #[error("hello.sensor: {0}")]
    HelloSensor(#[source] Box<RequestError>),
    /// A Hello's traversability thresholds out of their range.
    #[error("hello.{0}")]
    HelloTraversability(#[source] TraversabilityError),
    /// A Hello that asks for a map without a noise model.
    #[error(
        "hello.map: the map's height variance needs a sensor noise model: the camera's sensor \
         or hello.sensor"
    )]
    MapWithoutSensor,
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
    /// A camera message's noise coefficients that make no model.
    #[error("camera.{0}")]
    SensorCoefficients(#[source] CoefficientsError),
    /// A camera message with other than three noise coefficients.
    #[error("camera.sensor_sigma_mm: give exactly three coefficients [a, b, c], got {given}")]
    SensorCoefficientCount {
        /// How many were given.
        given: usize,
    },
    /// A camera message's depth scale that is not positive.
    #[error("camera.depth_scale: must be positive, got {scale}")]
    MessageDepthScale {
        /// The value given.
        scale: f64,
    },
    /// A stream frame with neither image nor depth.
    #[error("frame: neither image nor depth is set")]
    EmptyFrame,
    /// A stream frame's pose that is not one.
    #[error("frame.pose: {0}; 16 values, a 4×4 camera-to-world matrix row by row")]
    Pose(#[source] MapError),

    // The domain errors of the layers below.
    /// The frame does not fit the pipeline (or the pipeline failed). Boxed, as are the other
    /// pipeline errors: the largest error of the layers below.
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
    /// The code of this error, and so its HTTP status ([`ErrorCode::http_status`]): the one
    /// place that chooses them.
    #[allow(clippy::too_many_lines)] // One arm per kind of error: the table reads best whole.
    pub fn code(&self) -> ErrorCode {
        use ErrorCode as C;
        match self {
            Self::NoRoute { .. } | Self::NoStreamMap { .. } | Self::EmptyStreamMap { .. } => {
                C::NotFound
            }
            Self::MethodNotAllowed { .. } => C::MethodNotAllowed,
            Self::OriginNotAllowed { .. } => C::Forbidden,
            Self::NoApiKey | Self::WrongApiKey => C::Unauthorized,
            Self::TooManyRequests { .. }
            | Self::StreamsFull { .. }
            | Self::StreamsWaiting { .. } => C::TooManyRequests,
            Self::TooManyConnections { .. } | Self::QueueFull { .. } | Self::RequeueFailed => {
                C::Overloaded
            }
            Self::NotReady | Self::Loading | Self::ShuttingDown | Self::WorkersStopped => {
                C::NotReady
            }
            Self::Timeout { .. } => C::Timeout,
            Self::WorkerStopped | Self::Panic { .. } | Self::EncodePng(_) | Self::EncodeNpy(_) => {
                C::Internal
            }
            Self::BodyTimeout { .. } | Self::BodyTooSlow { .. } | Self::MessageTooSlow { .. } => {
                C::RequestTimeout
            }
            Self::BodyTooLarge { .. }
            | Self::MessageTooLarge { .. }
            | Self::SideTooLong { .. }
            | Self::TooManyPixels { .. } => C::TooLarge,
            Self::ContentType { .. } | Self::NotAnImage { .. } => C::UnsupportedMedia,
            Self::NotAWebSocket(_)
            | Self::ReadBody(_)
            | Self::Query { .. }
            | Self::MultipartHeader(_)
            | Self::MultipartBoundary(_)
            | Self::Multipart(_)
            | Self::MultipartField { .. }
            | Self::UnknownPart { .. }
            | Self::NoImagePart
            | Self::PartTwice { .. }
            | Self::CameraTwice
            | Self::Choice(_)
            | Self::DsacHypotheses(_)
            | Self::PreviewMax { .. }
            | Self::Traversability(_)
            | Self::Sensor(_)
            | Self::UnknownOutput { .. }
            | Self::NoInput
            | Self::NotAMessage(_)
            | Self::EmptyMessage
            | Self::TextMessage
            | Self::FrameBeforeHello
            | Self::UnknownValue { .. }
            | Self::HelloDsacHypotheses(_)
            | Self::HelloPreviewMax { .. }
            | Self::HelloSensorDescription { .. }
            | Self::HelloSensor(_)
            | Self::HelloTraversability(_)
            | Self::MapWithoutSensor
            | Self::MapCellSize { .. }
            | Self::MapSide { .. }
            | Self::MapSendRate { .. }
            | Self::MapGravity { .. }
            | Self::EmptyFrame
            | Self::Pose(_) => C::BadRequest,
            Self::EmptyImage { .. }
            | Self::Undecodable { .. }
            | Self::Jpeg { .. }
            | Self::DepthAsRgb { .. } => C::BadImage,
            // The shape of a depth part is a depth error, as the rest of what is wrong with it.
            Self::NoPixels { part, .. } | Self::TooNarrow { part, .. } => match part {
                ImagePart::Rgb => C::BadImage,
                ImagePart::Depth => C::BadDepth,
            },
            Self::NotDepth(_) | Self::DepthColour { .. } | Self::Depth(_) => C::BadDepth,
            Self::PartialIntrinsics
            | Self::CameraRange { .. }
            | Self::CameraSide { .. }
            | Self::CameraNotJson(_)
            | Self::CameraNotObject
            | Self::CameraFields(_)
            | Self::Camera(_)
            | Self::DepthScale { .. }
            | Self::SensorCoefficients(_)
            | Self::SensorCoefficientCount { .. }
            | Self::MessageDepthScale { .. }
            | Self::CameraSize(_)
            | Self::SensorSpec(_) => C::BadCamera,
            Self::Pipeline(e) => pipeline_code(e),
            // A client's `.npy` is its depth part: `too_large` when its header declares more
            // values than `--max-pixels`.
            Self::Npy(NpyError::TooLarge { .. }) => C::TooLarge,
            Self::Npy(_) => C::BadDepth,
        }
    }

    /// Whether this is an image beyond a decoding limit (`--max-side`, `--max-pixels`,
    /// `--max-aspect`), which the handler answers before the frame takes a place in the queue.
    pub(crate) fn is_over_limit(&self) -> bool {
        matches!(
            self,
            Self::SideTooLong { .. } | Self::TooManyPixels { .. } | Self::TooNarrow { .. }
        )
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

impl From<TooSlow> for RequestError {
    fn from(slow: TooSlow) -> Self {
        Self::MessageTooSlow {
            bytes: slow.bytes,
            secs: slow.secs,
            min_bytes_per_s: slow.min_bytes_per_s,
        }
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
