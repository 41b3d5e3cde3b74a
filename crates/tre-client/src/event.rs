//! What goes into a stream session ([`Frame`]) and what comes out of it ([`Event`]), in
//! domain types: maps as [`Grid`]s in metres, times as [`Duration`]s.

use std::sync::Arc;
use std::time::Duration;

use image::RgbImage;
use tokio_tungstenite::tungstenite;

use super::error::Chain;
use super::ClientError;
use tre_core::geometry::Grid;
use tre_core::kinds::MapFormat;
use tre_io::CameraFile;
use tre_proto::ErrorCode;

/// One camera frame to send.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Frame {
    /// PNG or JPEG bytes, sent as they are (may be empty in geometric mode).
    pub image: Vec<u8>,
    /// Registered depth: 16-bit grey PNG (the camera's `depth_scale` units per metre, default
    /// 1000) or float `.npy` in metres.
    pub depth: Option<Vec<u8>>,
    /// Overrides the session's camera for this frame.
    pub camera: Option<CameraFile>,
    /// Capture time, microseconds since the Unix epoch; `None`: the time of sending.
    pub timestamp_us: Option<i64>,
    /// Camera-to-world pose, a 4×4 rigid transform row by row (16 values), for the stream's
    /// map ([`ClientConfig::map`](super::ClientConfig::map)); `None`: the map is this frame
    /// alone.
    pub pose: Option<Vec<f64>>,
}

impl Frame {
    /// A frame of encoded RGB (PNG or JPEG) bytes.
    pub fn rgb(image: Vec<u8>) -> Self {
        Self {
            image,
            ..Self::default()
        }
    }

    /// The same frame with registered depth.
    pub fn with_depth(mut self, depth: Vec<u8>) -> Self {
        self.depth = Some(depth);
        self
    }
}

/// The roughness map of a result.
#[derive(Debug, Clone, PartialEq)]
pub enum Roughness {
    /// Metres per pixel, NaN where there is no data ([`MapFormat::Png16`], [`MapFormat::F32`]).
    Metres(Grid<f64>),
    /// The colour map ([`MapFormat::Color`]), the frame's size.
    Colour(RgbImage),
}

/// The roughness of one frame, as the server computed it.
#[derive(Debug, Clone, PartialEq)]
pub struct FrameResult {
    /// The frame's sequence number (assigned by [`FrameSender::send`](super::FrameSender::send)).
    pub sequence: u64,
    /// The frame's timestamp, echoed by the server.
    pub timestamp_us: i64,
    /// Width of the frame and the maps, pixels.
    pub width: usize,
    /// Height, pixels.
    pub height: usize,
    /// The decoded map.
    pub roughness: Roughness,
    /// The map as the server sent it (`format`-encoded): a PNG16 can be written out as is.
    pub encoded: Vec<u8>,
    /// How `encoded` is encoded.
    pub format: MapFormat,
    /// Traversability (`true`: traversable), if asked for.
    pub traversable: Option<Grid<bool>>,
    /// Three-state traversability, if asked for.
    pub traversal: Option<Grid<tre_core::roughness::traversal::Traversal>>,
    /// Uncertainty, metres (NaN: no data), if asked for.
    pub uncertainty_m: Option<Grid<f64>>,
    /// Wall time of each pipeline stage on the server.
    pub timings: Vec<(String, Duration)>,
    /// Round trip measured by the client: from [`FrameSender::send`](super::FrameSender::send)
    /// stamping the frame to its result decoded (`received_unix_us − sent_unix_us`, measured
    /// on the monotonic clock).
    pub latency: Duration,
    /// When `send` stamped the frame, microseconds since the Unix epoch (the start of
    /// `latency`; also the frame's timestamp unless [`Frame::timestamp_us`] gave one).
    pub sent_unix_us: i64,
    /// When the result was decoded, microseconds since the Unix epoch (the end of `latency`).
    pub received_unix_us: i64,
    /// Time from the frame's arrival at the server to its result.
    pub server_latency: Duration,
    /// Frames of this connection the server has dropped so far (latest frame wins).
    pub dropped_total: u64,
    /// The mode that ran (empty from a server that does not say).
    pub mode: String,
    /// What stood in for what the frame or the settings did not give (`intrinsics`,
    /// `depth_scale`, `mounting`, `mode`).
    pub assumed: Vec<String>,
    /// Where gravity came from, as the server words it (`stated; …`, `estimated; …`,
    /// `unknown; reason=…`).
    pub gravity: String,
}

impl FrameResult {
    /// The map in metres, unless the session asked for colour.
    pub fn roughness_m(&self) -> Option<&Grid<f64>> {
        match &self.roughness {
            Roughness::Metres(m) => Some(m),
            Roughness::Colour(_) => None,
        }
    }
}

/// The stream's grid map as the server sent it (docs/map.md): square layers of `side` cells,
/// row-major, column 0 at the window's smallest x, row 0 at its largest y, in the map frame.
#[derive(Debug, Clone, PartialEq)]
pub struct StreamMap {
    /// The last frame fused.
    pub sequence: u64,
    /// Cell side, metres.
    pub cell_m: f64,
    /// Cells along a side.
    pub side: usize,
    /// World cell index (x, y) of the window's lower-left cell.
    pub origin: (i64, i64),
    /// Rotation from the pose frame to the map frame, row by row.
    pub map_from_world: [f64; 9],
    /// The layers.
    pub layers: tre_core::map::Layers,
    /// Frames fused so far.
    pub fused: u64,
    /// Frames skipped so far (a pose too far, nothing seen, gravity unknown).
    pub skipped: u64,
}

/// Why a frame will get no answer.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum LostReason {
    /// It was in flight when the connection dropped.
    Disconnected,
    /// It was sent while the connection was down (fixed rate), so it never left.
    NotConnected,
    /// No answer within [`ClientConfig::frame_timeout`](super::ClientConfig::frame_timeout).
    TimedOut,
    /// More than [`ClientConfig::max_pending`](super::ClientConfig::max_pending) frames were
    /// awaiting answers; the oldest was forgotten.
    Evicted,
}

impl LostReason {
    /// Short name (`disconnected`, `not_connected`, `timed_out`, `evicted`).
    pub fn as_str(self) -> &'static str {
        match self {
            Self::Disconnected => "disconnected",
            Self::NotConnected => "not_connected",
            Self::TimedOut => "timed_out",
            Self::Evicted => "evicted",
        }
    }
}

/// What the server said about itself when it accepted the Hello.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct ServerInfo {
    /// Largest message it accepts, bytes.
    pub max_message_bytes: usize,
    /// Models it runs.
    pub models: Vec<String>,
}

/// Something that happened in a session. Every frame sent gets exactly one of `Result`,
/// `Dropped`, `Error` (with its sequence) or `Lost`.
///
/// Events compare field by field; the errors of `Disconnected` and `GaveUp` are equal when they
/// are the same error (an event and its clones), as errors have no equality of their own.
#[derive(Debug, Clone)]
pub enum Event {
    /// A frame's roughness.
    Result(Box<FrameResult>),
    /// The server skipped the frame: a newer one arrived before a worker was free.
    Dropped {
        /// The frame.
        sequence: u64,
        /// Frames of this connection dropped so far.
        dropped_total: u64,
    },
    /// The server could not use a message (or the client could not decode its answer:
    /// [`ErrorKind::BadResult`]).
    Error {
        /// The frame concerned, if any.
        sequence: Option<u64>,
        /// What kind of error: the server's stable code, or the client's own.
        code: ErrorKind,
        /// What went wrong, for a person: the server's message as it sent it (kinds
        /// [`ErrorKind::Server`] and [`ErrorKind::Unknown`]; the server's typed error is the
        /// code), or this client's [`ClientError`] as text (kinds [`ErrorKind::BadMessage`]
        /// and [`ErrorKind::BadResult`]), as it is shown and recorded.
        message: String,
    },
    /// A frame that will get no answer.
    Lost {
        /// The frame.
        sequence: u64,
        /// Why.
        reason: LostReason,
    },
    /// The connection dropped; the session is reconnecting.
    Disconnected {
        /// What ended it.
        reason: DisconnectReason,
    },
    /// A new connection is up and the Hello was accepted again.
    Reconnected {
        /// Attempts it took.
        attempts: u32,
        /// Time without a connection.
        downtime: Duration,
        /// The server's Ready.
        server: ServerInfo,
    },
    /// The stream's grid map after a frame was answered (only when the session asks for a
    /// map: [`ClientConfig::map`](super::ClientConfig::map)).
    Map(Box<StreamMap>),
    /// Reconnecting failed as often as allowed, or a new connection was refused; the session
    /// has ended and this is its last event.
    GaveUp {
        /// What failed last: [`ClientError::GaveUp`] with the last attempt's error, or the
        /// refusal that retrying will not fix.
        reason: Arc<ClientError>,
    },
}

/// Why a connection dropped ([`Event::Disconnected`]). Reasons compare by case and value; the
/// socket's errors are equal when they are the same error (a reason and its clones).
// The cause is in the message, not a `source`: a report that prints the chain would say it
// twice. The errors are shared (`Arc`) so that the event stays `Clone`.
#[derive(Debug, Clone, thiserror::Error)]
pub enum DisconnectReason {
    /// Writing a frame to the socket failed.
    #[error("sending a frame: {}", Chain(.0))]
    Send(Arc<tungstenite::Error>),
    /// Reading from the socket failed.
    #[error("{}", Chain(.0))]
    Read(Arc<tungstenite::Error>),
    /// The server closed the stream, with its close code and reason if it gave them.
    #[error("the server closed the stream{}", .0.as_ref().map_or_else(String::new, |c| format!(" ({} {})", u16::from(c.code), c.reason)))]
    ServerClosed(Option<tungstenite::protocol::CloseFrame>),
    /// Nothing was heard from the server for
    /// [`ClientConfig::silence_timeout`](super::ClientConfig::silence_timeout).
    #[error("nothing heard from the server for {} s", .0.as_secs_f64())]
    Silence(Duration),
    /// The connection ended without a close.
    #[error("the connection ended")]
    Ended,
}

impl PartialEq for DisconnectReason {
    fn eq(&self, other: &Self) -> bool {
        match (self, other) {
            (Self::Send(a), Self::Send(b)) | (Self::Read(a), Self::Read(b)) => Arc::ptr_eq(a, b),
            (Self::ServerClosed(a), Self::ServerClosed(b)) => a == b,
            (Self::Silence(a), Self::Silence(b)) => a == b,
            (Self::Ended, Self::Ended) => true,
            _ => false,
        }
    }
}

impl PartialEq for Event {
    fn eq(&self, other: &Self) -> bool {
        match (self, other) {
            (Self::Result(a), Self::Result(b)) => a == b,
            (
                Self::Dropped {
                    sequence: a,
                    dropped_total: x,
                },
                Self::Dropped {
                    sequence: b,
                    dropped_total: y,
                },
            ) => (a, x) == (b, y),
            (
                Self::Error {
                    sequence: a,
                    code: x,
                    message: m,
                },
                Self::Error {
                    sequence: b,
                    code: y,
                    message: n,
                },
            ) => (a, x, m) == (b, y, n),
            (
                Self::Lost {
                    sequence: a,
                    reason: x,
                },
                Self::Lost {
                    sequence: b,
                    reason: y,
                },
            ) => (a, x) == (b, y),
            (Self::Disconnected { reason: a }, Self::Disconnected { reason: b }) => a == b,
            (
                Self::Reconnected {
                    attempts: a,
                    downtime: x,
                    server: m,
                },
                Self::Reconnected {
                    attempts: b,
                    downtime: y,
                    server: n,
                },
            ) => (a, x, m) == (b, y, n),
            (Self::GaveUp { reason: a }, Self::GaveUp { reason: b }) => Arc::ptr_eq(a, b),
            (Self::Map(a), Self::Map(b)) => a == b,
            _ => false,
        }
    }
}

impl Event {
    /// The frame this event settles, if it is one's final answer.
    pub fn settles(&self) -> Option<u64> {
        match self {
            Self::Result(r) => Some(r.sequence),
            Self::Dropped { sequence, .. } | Self::Lost { sequence, .. } => Some(*sequence),
            Self::Error { sequence, .. } => *sequence,
            _ => None,
        }
    }
}

/// The kind of an [`Event::Error`]: a code the server sent ([`ErrorCode`], shared with the
/// server through `tre-proto`), one this client does not know (a newer server's), or the
/// client's own failure to read the server's message.
#[derive(Debug, Clone, PartialEq, Eq, Hash)]
pub enum ErrorKind {
    /// A code the server sent.
    Server(ErrorCode),
    /// A code this client does not know, as the server sent it.
    Unknown(String),
    /// A server message this client could not decode.
    BadMessage,
    /// A Result whose maps this client could not decode.
    BadResult,
}

impl ErrorKind {
    /// The kind of a code as it came on the wire.
    #[must_use]
    pub fn from_wire(code: &str) -> Self {
        code.parse()
            .map_or_else(|_| Self::Unknown(code.to_owned()), Self::Server)
    }

    /// The stable name (`bad_image`, `overloaded`, `bad_result`, ...).
    #[must_use]
    pub fn as_str(&self) -> &str {
        match self {
            Self::Server(code) => code.as_str(),
            Self::Unknown(code) => code,
            Self::BadMessage => "bad_message",
            Self::BadResult => "bad_result",
        }
    }
}

impl std::fmt::Display for ErrorKind {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.as_str())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn wire_codes_are_the_servers_and_unknown_ones_are_kept() {
        assert_eq!(
            ErrorKind::from_wire("overloaded"),
            ErrorKind::Server(ErrorCode::Overloaded)
        );
        let newer = ErrorKind::from_wire("teapot");
        assert_eq!(newer, ErrorKind::Unknown("teapot".into()));
        assert_eq!(newer.as_str(), "teapot");
        assert_eq!(ErrorKind::BadResult.to_string(), "bad_result");
    }

    #[test]
    fn disconnections_say_why() {
        let silence = DisconnectReason::Silence(Duration::from_millis(1500));
        assert_eq!(
            silence.to_string(),
            "nothing heard from the server for 1.5 s"
        );
        let closed = DisconnectReason::ServerClosed(Some(tungstenite::protocol::CloseFrame {
            code: tungstenite::protocol::frame::coding::CloseCode::Away,
            reason: "shutting down".into(),
        }));
        assert_eq!(
            closed.to_string(),
            "the server closed the stream (1001 shutting down)"
        );
        assert_eq!(
            DisconnectReason::ServerClosed(None).to_string(),
            "the server closed the stream"
        );
        let io = std::io::Error::new(std::io::ErrorKind::BrokenPipe, "broken pipe");
        let sent = DisconnectReason::Send(Arc::new(tungstenite::Error::Io(io)));
        assert_eq!(sent.to_string(), "sending a frame: IO error: broken pipe");
        let event = Event::Disconnected { reason: sent };
        assert_eq!(event.clone(), event);
        assert_ne!(event, Event::Disconnected { reason: silence });
    }
}
