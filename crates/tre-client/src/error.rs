//! Errors of the streaming client: settings, connecting, the server's answers and the frame
//! sources. Each variant carries what is needed to act on it.

use std::path::PathBuf;

/// Everything the client layer can fail with.
#[derive(Debug, thiserror::Error)]
pub enum ClientError {
    /// The server address cannot be used.
    #[error("server address {url:?}: {reason}")]
    BadUrl {
        /// The address as given.
        url: String,
        /// What is wrong with it.
        reason: String,
    },
    /// A setting out of range.
    #[error("client setting {field}: {reason}")]
    BadConfig {
        /// The setting (as named in `ClientConfig`).
        field: &'static str,
        /// What is wrong with it.
        reason: String,
    },
    /// The server could not be reached or the WebSocket handshake failed; worth retrying.
    #[error("connecting to {url}: {reason}")]
    Connect {
        /// The WebSocket URL.
        url: String,
        /// What failed.
        reason: String,
    },
    /// The server refused the connection in a way retrying will not fix (HTTP 4xx on the
    /// upgrade, e.g. a wrong path).
    #[error("{url} refused the stream: {reason}")]
    Rejected {
        /// The WebSocket URL.
        url: String,
        /// The HTTP status or the reason.
        reason: String,
    },
    /// The server answered the Hello with an error (e.g. nonsense intrinsics).
    #[error("the server refused the Hello: {code}: {message}")]
    HelloRefused {
        /// The server's code (`bad_camera`, `bad_request`, ...).
        code: crate::ErrorKind,
        /// The server's message.
        message: String,
    },
    /// `/readyz` did not answer 200 (models still loading, or the server at a limit such as
    /// `--max-connections`); worth retrying.
    #[error("{url}: the server cannot take the stream yet ({status})")]
    NotReady {
        /// The readiness URL.
        url: String,
        /// HTTP status, with the server's error code and message when it sent them.
        status: String,
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
    Protocol(String),
    /// A Result whose map cannot be decoded or does not match its stated size.
    #[error("result for frame {sequence}: {reason}")]
    BadResult {
        /// The frame's sequence number.
        sequence: u64,
        /// What is wrong with it.
        reason: String,
    },
    /// Reconnecting failed as many times as allowed.
    #[error("gave up after {attempts} connection attempts; last: {last}")]
    GaveUp {
        /// Attempts made.
        attempts: u32,
        /// The last attempt's error.
        last: String,
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
    #[error("{}: {reason}", path.display())]
    Source {
        /// The file or folder.
        path: PathBuf,
        /// What went wrong.
        reason: String,
    },
    /// Video or camera input without an `ffmpeg` executable on `PATH`.
    #[error("{input}: reading video files and camera devices needs the `ffmpeg` executable on PATH (it is spawned to decode frames to PNG); install ffmpeg, or extract the frames to a folder and use --frames")]
    FfmpegMissing {
        /// The video file or device asked for.
        input: String,
    },
    /// `ffmpeg` failed or produced a stream that is not PNG images.
    #[error("ffmpeg on {input}: {reason}")]
    Ffmpeg {
        /// The video file or device.
        input: String,
        /// Its error output or what was wrong with the stream.
        reason: String,
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
