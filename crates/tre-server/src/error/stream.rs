//! Refusals of the stream's messages as such: the upgrade, the message's encoding, the order of
//! Hello and frames, a frame's fields.

use axum::extract::ws::rejection::WebSocketUpgradeRejection;
use tre_core::map::MapError;
use tre_proto::ErrorCode;

/// A stream request or message that does not follow the protocol.
#[derive(Debug, thiserror::Error)]
pub enum StreamError {
    /// The stream's route asked for without a WebSocket upgrade.
    #[error("/v1/stream is a WebSocket: {}", .0.body_text())]
    NotAWebSocket(#[source] WebSocketUpgradeRejection),
    /// A binary message that is not a `ClientMessage`.
    #[error("message: not a roughness.v1.ClientMessage: {0}")]
    NotAMessage(#[source] prost::DecodeError),
    /// A `ClientMessage` with neither a Hello nor a frame.
    #[error("message: empty ClientMessage (neither hello nor frame)")]
    EmptyMessage,
    /// A text message.
    #[error("text messages are not part of the protocol; send binary roughness.v1.ClientMessage")]
    TextMessage,
    /// A frame before the stream's Hello.
    #[error("send a Hello before the first frame")]
    FrameBeforeHello,
    /// A stream frame with neither image nor depth.
    #[error("frame: neither image nor depth is set")]
    EmptyFrame,
    /// A stream frame's pose that is not one.
    #[error("frame.pose: {0}; 16 values, a 4×4 camera-to-world matrix row by row")]
    Pose(#[source] MapError),
}

impl StreamError {
    /// The code of this error in the one [`ErrorCode`] table: all are the client's fault.
    pub fn code(&self) -> ErrorCode {
        match self {
            Self::NotAWebSocket(_)
            | Self::NotAMessage(_)
            | Self::EmptyMessage
            | Self::TextMessage
            | Self::FrameBeforeHello
            | Self::EmptyFrame
            | Self::Pose(_) => ErrorCode::BadRequest,
        }
    }
}
