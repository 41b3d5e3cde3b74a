//! Errors of the streaming client: settings, connecting, the server's answers and the frame
//! sources. Each variant carries what is needed to act on it, the cause typed: the underlying
//! error, or one case of a small enum of what the client checks.
//!
//! Throughout the client, a cause is in the message, not a `source`: the error reads whole
//! where it is shown on its own (the progress notices, the logs, [`Event::Error`]), and a
//! report that prints the chain (`{:#}` of `anyhow`) does not say it twice. Foreign errors
//! whose own sources carry the detail (reqwest's, tungstenite's) are written with those
//! sources on the same line.
//!
//! [`Event::Error`]: crate::Event::Error

use std::fmt;
use std::time::Duration;

use tokio_tungstenite::tungstenite;
use tre_core::geometry::GeometryError;

#[cfg(feature = "app")]
use crate::source::{FfmpegProblem, SourceProblem};
use crate::tls::TlsError;
use crate::ErrorKind;

/// Everything the client layer can fail with.
// Every cause below is in the message, not a `source` (see the module's documentation).
#[derive(Debug, thiserror::Error)]
pub enum ClientError {
    /// The server address cannot be used.
    #[error("server address {url:?}: {reason}")]
    BadUrl {
        /// The address as given.
        url: String,
        /// What is wrong with it.
        reason: UrlProblem,
    },
    /// A setting out of range.
    #[error("client setting {field}: {reason}")]
    BadConfig {
        /// The setting (as named in `ClientConfig`).
        field: &'static str,
        /// What is wrong with it.
        reason: ConfigProblem,
    },
    /// The server could not be reached or the WebSocket handshake failed; worth retrying.
    #[error("connecting to {url}: {reason}")]
    Connect {
        /// The WebSocket URL (the readiness URL when the readiness check failed).
        url: String,
        /// What failed.
        reason: ConnectProblem,
    },
    /// The server refused the connection in a way retrying will not fix (HTTP 4xx on the
    /// upgrade, e.g. a wrong path).
    #[error("{url} refused the stream: {reason}")]
    Rejected {
        /// The WebSocket URL.
        url: String,
        /// The HTTP answer, or what is wrong with the URL.
        reason: RejectProblem,
    },
    /// The server answered the Hello with an error (e.g. nonsense intrinsics).
    #[error("the server refused the Hello: {code}: {message}")]
    HelloRefused {
        /// The server's code (`bad_camera`, `bad_request`, ...).
        code: ErrorKind,
        /// The server's message.
        message: String,
    },
    /// `/readyz` did not answer 200 (models still loading, or the server at a limit such as
    /// `--max-connections`); worth retrying.
    #[error(
        "{url}: the server cannot take the stream yet (HTTP {}{})",
        .status.as_u16(),
        after_comma(.server)
    )]
    NotReady {
        /// The readiness URL.
        url: String,
        /// The HTTP status.
        status: tungstenite::http::StatusCode,
        /// The server's error code and message, when it sent them.
        server: Option<ServerSaid>,
    },
    /// A step of the connection took longer than allowed.
    #[error("{what} took longer than {ms} ms")]
    Timeout {
        /// The step.
        what: &'static str,
        /// The limit, milliseconds.
        ms: u128,
    },
    /// A server message that is not valid `roughness.v1.ServerMessage`, or came out of order.
    #[error("bad message from the server: {0}")]
    Protocol(ProtocolProblem),
    /// A Result whose map cannot be decoded or does not match its stated size.
    #[error("result for frame {sequence}: {reason}")]
    BadResult {
        /// The frame's sequence number.
        sequence: u64,
        /// What is wrong with it.
        reason: ResultProblem,
    },
    /// Reconnecting failed as many times as allowed.
    #[error("gave up after {attempts} connection attempts; last: {last}")]
    GaveUp {
        /// Attempts made.
        attempts: u32,
        /// The last attempt's error.
        last: Box<ClientError>,
    },
    /// The session has ended (gave up, or the connection task stopped).
    #[error("the stream session has ended")]
    Closed,
    /// An encoded frame larger than the server accepts.
    #[error("frame of {bytes} bytes is larger than the server's limit of {limit}")]
    FrameTooLarge {
        /// Encoded size.
        bytes: usize,
        /// The server's `max_message_bytes`.
        limit: usize,
    },
    /// A frame source file or folder that cannot be read.
    #[cfg(feature = "app")]
    #[error("{}: {reason}", path.display())]
    Source {
        /// The file or folder.
        path: std::path::PathBuf,
        /// What went wrong.
        reason: SourceProblem,
    },
    /// Video or camera input without an `ffmpeg` executable on `PATH`.
    #[cfg(feature = "app")]
    #[error("{input}: reading video files and camera devices needs the `ffmpeg` executable on PATH (it is spawned to decode frames to PNG); install ffmpeg, or extract the frames to a folder and use --frames")]
    FfmpegMissing {
        /// The video file or device asked for.
        input: String,
    },
    /// `ffmpeg` failed or produced a stream that is not PNG images.
    #[cfg(feature = "app")]
    #[error("ffmpeg on {input}: {reason}")]
    Ffmpeg {
        /// The video file or device.
        input: String,
        /// What went wrong: starting it, its exit, or its stream.
        reason: FfmpegProblem,
    },
}

impl ClientError {
    /// Whether connecting again may succeed (as opposed to a setting or refusal that will not
    /// change).
    pub fn is_retryable(&self) -> bool {
        matches!(
            self,
            Self::Connect { .. } | Self::NotReady { .. } | Self::Timeout { .. } | Self::Protocol(_)
        )
    }
}

/// What is wrong with a server address ([`ClientError::BadUrl`]).
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum UrlProblem {
    /// A scheme other than `ws`, `wss`, `http` and `https`.
    #[error("the scheme must be ws://, wss://, http:// or https://")]
    Scheme(
        /// The scheme given, lower case.
        String,
    ),
    /// A query, fragment or space in the address.
    #[error("no query, fragment or spaces expected")]
    QueryOrSpaces,
    /// No host before the port or path.
    #[error("no host")]
    NoHost,
}

/// What is wrong with a setting ([`ClientError::BadConfig`]).
// The cause is in the message, not a `source` (see the module's documentation).
#[derive(Debug, thiserror::Error)]
pub enum ConfigProblem {
    /// A fixed rate that is not a positive number of frames per second.
    #[error("frames per second must be positive, got {0}")]
    Rate(f64),
    /// Traversability thresholds out of range, in the words of `tre-core`'s check.
    #[error("{0}")]
    Traversability(tre_core::kinds::TraversabilityError),
    /// A back-off whose first wait is zero or longer than its longest.
    #[error("need 0 < initial ≤ max, got {initial:?} and {max:?}")]
    BackoffRange {
        /// The first wait.
        initial: Duration,
        /// The longest wait.
        max: Duration,
    },
    /// A back-off growth below 1 (or not finite).
    #[error("must be ≥ 1, got {0}")]
    BackoffFactor(f64),
    /// A give-up allowance of zero attempts.
    #[error("must be ≥ 1 (None: never)")]
    NoAttempts,
    /// A zero duration.
    #[error("must be positive")]
    ZeroDuration,
    /// A zero count.
    #[error("must be ≥ 1")]
    ZeroCount,
    /// A number that must be positive (and finite).
    #[error("must be positive, got {0}")]
    NotPositive(f64),
    /// Camera intrinsics or mounting that make no camera.
    #[error("{0}")]
    Camera(GeometryError),
    /// Map settings out of range.
    #[error("cells of 1 mm to 1 m, 1 to 1000 a side, gravity of 3 finite values not all zero")]
    Map,
    /// An API key that cannot be sent in an HTTP header.
    #[error("not a valid header value")]
    HeaderValue(tungstenite::http::header::InvalidHeaderValue),
    /// The TLS settings (`--ca-cert`).
    #[error("{0}")]
    Tls(Box<TlsError>),
    /// The HTTP client of the readiness check cannot be made.
    #[error("cannot make an HTTP client: {}", Chain(.0))]
    HttpClient(reqwest::Error),
}

/// Why a connection attempt failed in a way worth retrying ([`ClientError::Connect`]).
// The cause is in the message, not a `source` (see the module's documentation).
#[derive(Debug, thiserror::Error)]
pub enum ConnectProblem {
    /// The readiness check's request failed (no server there, a reset, TLS, ...).
    #[error("{}", Chain(.0))]
    Http(reqwest::Error),
    /// The WebSocket handshake, or sending the Hello or reading the answer, failed.
    #[error("{}", Chain(.0))]
    WebSocket(tungstenite::Error),
    /// The upgrade was answered with an HTTP status that may change (5xx, 408, 429).
    #[error("{0}")]
    Upgrade(UpgradeAnswer),
    /// The server closed the connection before answering the Hello.
    #[error("the connection closed before Ready")]
    ClosedBeforeReady,
}

/// Why the server refused the stream for good ([`ClientError::Rejected`]).
// The cause is in the message, not a `source` (see the module's documentation).
#[derive(Debug, thiserror::Error)]
pub enum RejectProblem {
    /// The upgrade was answered with an HTTP 4xx status (but 408 and 429).
    #[error("{0}")]
    Upgrade(UpgradeAnswer),
    /// The WebSocket URL cannot be requested.
    #[error("URL error: {0}")]
    Url(tungstenite::error::UrlError),
}

/// The HTTP answer to a WebSocket upgrade that did not switch protocols.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("HTTP {status} on the WebSocket upgrade{}", after_comma(.server))]
pub struct UpgradeAnswer {
    /// The HTTP status.
    pub status: tungstenite::http::StatusCode,
    /// The server's error code and message, when it sent them.
    pub server: Option<ServerSaid>,
}

/// The server's own account of an HTTP refusal: its JSON error body
/// (`{"error": {"code": ..., "message": ...}}`).
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct ServerSaid {
    /// The server's code (`overloaded`, `not_ready`, ...).
    pub code: ErrorKind,
    /// The server's message.
    pub message: String,
}

impl ServerSaid {
    /// The error in a JSON error body, if `body` is one.
    pub(crate) fn from_body(body: &[u8]) -> Option<Self> {
        let v = serde_json::from_slice::<serde_json::Value>(body).ok()?;
        let e = v.get("error")?;
        Some(Self {
            code: ErrorKind::from_wire(e.get("code")?.as_str()?),
            message: e.get("message")?.as_str()?.to_owned(),
        })
    }
}

impl fmt::Display for ServerSaid {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}: {}", self.code, self.message)
    }
}

/// `, code: message` when the server said why, else nothing.
fn after_comma(server: &Option<ServerSaid>) -> impl fmt::Display + '_ {
    struct After<'a>(&'a Option<ServerSaid>);
    impl fmt::Display for After<'_> {
        fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
            match self.0 {
                Some(s) => write!(f, ", {s}"),
                None => Ok(()),
            }
        }
    }
    After(server)
}

/// What is wrong with a server message ([`ClientError::Protocol`]).
// The cause is in the message, not a `source` (see the module's documentation).
#[derive(Debug, thiserror::Error)]
pub enum ProtocolProblem {
    /// Bytes that do not decode as a `roughness.v1.ServerMessage`.
    #[error("not a roughness.v1.ServerMessage: {0}")]
    Decode(prost::DecodeError),
    /// A `ServerMessage` with nothing in it.
    #[error("empty ServerMessage")]
    Empty,
    /// The answer to the Hello was neither Ready nor an Error.
    #[error("expected Ready after the Hello, got {got}")]
    ExpectedReady {
        /// What came (`Result`, `Dropped`, `Map`).
        got: &'static str,
    },
    /// A MapUpdate whose layers do not make a map.
    #[error("MapUpdate: {0}")]
    BadMap(MapUpdateProblem),
}

/// Why a MapUpdate's fields do not make a map ([`ProtocolProblem::BadMap`]).
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum MapUpdateProblem {
    /// A `map_from_world` that is not 9 values.
    #[error("{0} map_from_world values")]
    Transform(usize),
    /// A layer the map needs is missing.
    #[error("no {0} layer")]
    NoLayer(&'static str),
    /// A layer whose bytes are not 4 per cell.
    #[error("{name}: {bytes} bytes for {side}×{side} cells")]
    LayerSize {
        /// The layer.
        name: &'static str,
        /// Its bytes.
        bytes: usize,
        /// The map's side, cells.
        side: usize,
    },
    /// A layer's cells that do not make a grid.
    #[error("{name}: {reason}")]
    Grid {
        /// The layer.
        name: &'static str,
        /// Why.
        reason: GeometryError,
    },
}

/// What is wrong with a Result ([`ClientError::BadResult`]).
// The cause is in the message, not a `source` (see the module's documentation).
#[derive(Debug, thiserror::Error)]
pub enum ResultProblem {
    /// A frame of no pixels.
    #[error("width × height is {width}×{height}")]
    ZeroSize {
        /// Width, pixels.
        width: usize,
        /// Height, pixels.
        height: usize,
    },
    /// A map encoding this client does not know.
    #[error("format: unknown value {0}")]
    UnknownFormat(i32),
    /// A map that does not decode to the frame's size.
    #[error("{map}: {reason}")]
    Map {
        /// The map (`roughness`, `uncertainty`, `traversable`, `traversal`).
        map: &'static str,
        /// What is wrong with it.
        reason: MapProblem,
    },
    /// A byte map of the wrong length.
    #[error("{map}: {bytes} bytes for {width}×{height} pixels")]
    ByteCount {
        /// The map (`traversable`, `traversal`).
        map: &'static str,
        /// Its length.
        bytes: usize,
        /// Width of the frame, pixels.
        width: usize,
        /// Height of the frame, pixels.
        height: usize,
    },
    /// A three-state traversability byte other than 0, 1 or 2.
    #[error("traversal: byte {0} is not 0, 1 or 2")]
    TraversalByte(u8),
    /// A time that is not a duration (negative, not finite).
    #[error("{field}: {ms} ms is not a duration")]
    Duration {
        /// The field (`timings`, `latency_ms`).
        field: &'static str,
        /// Its value, milliseconds.
        ms: f64,
    },
}

/// What is wrong with one map of a Result ([`ResultProblem::Map`]).
// The cause is in the message, not a `source` (see the module's documentation).
#[derive(Debug, thiserror::Error)]
pub enum MapProblem {
    /// PNG bytes that do not decode.
    #[error("not a readable PNG: {0}")]
    Png(Box<image::ImageError>),
    /// A `png16` map that is not 16-bit grey with alpha.
    #[error("expected 16-bit grey + alpha, got {0:?}")]
    NotGreyAlpha16(image::ColorType),
    /// An image of another size than the frame.
    #[error("a {}×{} image for a {}×{} frame", .image.0, .image.1, .frame.0, .frame.1)]
    SizeMismatch {
        /// The image's width and height.
        image: (u32, u32),
        /// The frame's width and height.
        frame: (usize, usize),
    },
    /// A float32 map of the wrong length.
    #[error("{bytes} bytes of float32 for {width}×{height} pixels")]
    Float32Bytes {
        /// Its length.
        bytes: usize,
        /// Width of the frame, pixels.
        width: usize,
        /// Height of the frame, pixels.
        height: usize,
    },
    /// Values that do not fill the frame's grid.
    #[error("{0}")]
    Grid(GeometryError),
}

/// An error with its sources on one line (`a: b: c`), leaving out a source whose words are
/// already there (many errors repeat their source in their own message).
pub(crate) struct Chain<'a>(pub &'a (dyn std::error::Error + 'static));

impl fmt::Display for Chain<'_> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let mut text = self.0.to_string();
        let mut source = self.0.source();
        while let Some(s) = source {
            let words = s.to_string();
            if !text.contains(&words) {
                text.push_str(": ");
                text.push_str(&words);
            }
            source = s.source();
        }
        f.write_str(&text)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[derive(Debug, thiserror::Error)]
    #[error("outer: {0}")]
    struct Repeats(#[source] std::io::Error);

    #[derive(Debug, thiserror::Error)]
    #[error("top")]
    struct Quiet(#[source] Repeats);

    #[test]
    fn a_chain_is_one_line_without_repeats() {
        let io = || std::io::Error::other("refused");
        assert_eq!(Chain(&Repeats(io())).to_string(), "outer: refused");
        assert_eq!(
            Chain(&Quiet(Repeats(io()))).to_string(),
            "top: outer: refused"
        );
    }

    #[test]
    fn refusals_carry_the_servers_words() {
        let body = br#"{"error": {"code": "overloaded", "message": "at --max-connections"}}"#;
        let e = ClientError::NotReady {
            url: "http://h/readyz".into(),
            status: tungstenite::http::StatusCode::SERVICE_UNAVAILABLE,
            server: ServerSaid::from_body(body),
        };
        assert_eq!(
            e.to_string(),
            "http://h/readyz: the server cannot take the stream yet (HTTP 503, overloaded: at --max-connections)"
        );
        let e = ClientError::Rejected {
            url: "ws://h/v1/stream".into(),
            reason: RejectProblem::Upgrade(UpgradeAnswer {
                status: tungstenite::http::StatusCode::NOT_FOUND,
                server: ServerSaid::from_body(b"not json"),
            }),
        };
        assert_eq!(
            e.to_string(),
            "ws://h/v1/stream refused the stream: HTTP 404 Not Found on the WebSocket upgrade"
        );
        assert!(!e.is_retryable());
    }

    #[test]
    fn causes_are_told_once_in_a_printed_chain() {
        let e = ClientError::GaveUp {
            attempts: 3,
            last: Box::new(ClientError::Connect {
                url: "ws://h/v1/stream".into(),
                reason: ConnectProblem::ClosedBeforeReady,
            }),
        };
        assert!(std::error::Error::source(&e).is_none());
        assert_eq!(
            e.to_string(),
            "gave up after 3 connection attempts; last: connecting to ws://h/v1/stream: the connection closed before Ready"
        );
    }
}
