//! Why a URL, a frame file or a stream's setup failed: the reasons behind `LoadError`'s
//! `Url`, `Frame` and `Stream` variants, typed so that a caller can match on them.

use std::net::SocketAddr;

use tokio_tungstenite::tungstenite;

/// What is wrong with a `--url`.
#[derive(Debug, thiserror::Error)]
pub enum UrlProblem {
    /// It does not parse as a URL.
    #[error(transparent)]
    Parse(#[from] url::ParseError),
    /// Its scheme is not `http`, `https`, `ws` or `wss`.
    #[error("expected http://host:port or https://host:port")]
    Scheme,
    /// It has a query or a fragment.
    #[error("no query or fragment, only http://host:port[/prefix]")]
    QueryOrFragment,
    /// It names no host.
    #[error("no host")]
    NoHost,
}

/// Why a frame file, or a folder of them, cannot be used.
#[derive(Debug, thiserror::Error)]
pub enum FrameProblem {
    /// The file or folder cannot be read.
    #[error(transparent)]
    Read(#[from] std::io::Error),
    /// A depth file that is neither a PNG nor a `.npy`.
    #[error("depth must be a 16-bit PNG or a float .npy")]
    DepthFormat,
    /// A frame file that is neither a PNG nor a JPEG.
    #[error("not a PNG or JPEG")]
    NotAnImage,
    /// A folder with no file of the extensions looked for.
    #[error("no {} file in this folder", dotted(.extensions))]
    NoFile {
        /// The extensions looked for, without their dots.
        extensions: Vec<String>,
    },
}

/// `.a or .b` of `extensions`.
fn dotted(extensions: &[String]) -> String {
    let names: Vec<String> = extensions.iter().map(|e| format!(".{e}")).collect();
    names.join(" or ")
}

/// Why a stream could not be opened up to its Ready.
#[derive(Debug, thiserror::Error)]
pub enum StreamProblem {
    /// The TCP connection failed.
    #[error("connecting to {addr}: {source}")]
    Connect {
        /// The address.
        addr: SocketAddr,
        /// Why.
        source: std::io::Error,
    },
    /// A socket option could not be set.
    #[error(transparent)]
    Socket(std::io::Error),
    /// The request or a message failed at the WebSocket layer.
    #[error(transparent)]
    WebSocket(#[from] tungstenite::Error),
    /// The WebSocket handshake failed.
    #[error("handshake: {0}")]
    Handshake(tungstenite::Error),
    /// An answer that does not decode.
    #[error(transparent)]
    Decode(#[from] AnswerProblem),
    /// The first answer was not Ready.
    #[error("expected Ready, got {0:?}")]
    NotReady(FirstAnswer),
    /// The service closed the stream before Ready.
    #[error("closed before Ready")]
    Closed,
    /// No Ready within the timeout.
    #[error("no Ready within {timeout_ms} ms")]
    Timeout {
        /// The timeout, milliseconds.
        timeout_ms: u128,
    },
}

/// The first answer to the Hello when it was not Ready ([`StreamProblem::NotReady`]); the
/// message shows it as written here (`Result(3)`, `Error { sequence: None, code: "…" }`).
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum FirstAnswer {
    /// A result for frame `sequence`.
    Result(u64),
    /// Frame `sequence` was skipped for a newer one.
    Dropped(u64),
    /// An error, for one frame or for the stream.
    Error {
        /// The frame, if the error concerns one.
        sequence: Option<u64>,
        /// Its stable error code.
        code: String,
    },
}

/// Why a `ServerMessage` does not decode.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum AnswerProblem {
    /// Not protobuf of a `ServerMessage`.
    #[error(transparent)]
    Protobuf(#[from] prost::DecodeError),
    /// A message with nothing in it.
    #[error("empty ServerMessage")]
    Empty,
}
