//! The robot-side client of the WebSocket stream (`GET /v1/stream`): connect with a
//! [`ClientConfig`], send [`Frame`]s, receive [`Event`]s with the roughness decoded to metres;
//! the session paces frames ([`Rate`]), matches answers to frames by sequence number, times
//! frames out, and reconnects with exponential back-off ([`Backoff`]) when the connection
//! drops, reporting the frames that were in flight as lost. [`source`] reads frames from a
//! folder, or from a video file or camera through `ffmpeg`; [`recorder`] streams a source and
//! writes every answer to disk (`tre client`).
//!
//! Failures are [`ClientError`]s, each with its cause typed (the underlying error, or a case of
//! a small enum such as [`UrlProblem`] or [`ResultProblem`]) and told in its message, so that
//! one line says it all; [`ClientError::is_retryable`] tells a failure worth another attempt
//! from one that will not change. A dropped connection is an [`Event::Disconnected`] with its
//! [`DisconnectReason`]; a session that ends for good says why with [`Event::GaveUp`].
//!
//! ```no_run
//! # async fn demo() -> Result<(), tre_client::ClientError> {
//! use tre_client::{ClientConfig, ClientError, Event, Frame, Rate, Session};
//! let cfg = ClientConfig {
//!     server: "ws://10.0.0.2:8080/v1/stream".into(),
//!     rate: Rate::Fixed(10.0),
//!     ..ClientConfig::default()
//! };
//! let (mut frames, mut events) = Session::connect(cfg).await?.split();
//! tokio::spawn(async move {
//!     loop {
//!         let png = std::fs::read("frame.png").unwrap_or_default(); // the robot's camera
//!         if frames.send(Frame::rgb(png)).await.is_err() {
//!             break;
//!         }
//!     }
//! });
//! while let Some(event) = events.recv().await {
//!     match event {
//!         Event::Result(r) => println!("frame {}: {} ms", r.sequence, r.latency.as_millis()),
//!         Event::Dropped { sequence, .. } => println!("frame {sequence}: skipped by the server"),
//!         Event::Disconnected { reason } => eprintln!("disconnected ({reason}); reconnecting"),
//!         Event::GaveUp { reason } => {
//!             // The session has ended: reconnecting failed as often as allowed, or the server
//!             // refused it for good.
//!             eprintln!("gave up: {reason}");
//!             if let ClientError::GaveUp { last, .. } = &*reason {
//!                 eprintln!("worth retrying later: {}", last.is_retryable());
//!             }
//!         }
//!         other => println!("{other:?}"),
//!     }
//! }
//! # Ok(())
//! # }
//! ```

#[cfg(feature = "cli")]
mod cli;
mod clock;
mod config;
mod connection;
mod error;
mod event;
mod proto;
#[cfg(feature = "app")]
pub mod recorder;
mod session;
#[cfg(feature = "app")]
pub mod source;
pub mod tls;

#[cfg(feature = "cli")]
pub use cli::{ArgsError, ClientArgs, MapArgProblem};
pub use clock::unix_us;
pub use config::{endpoints, Backoff, ClientConfig, Endpoints, MapRequest, Rate};
pub use error::{
    ClientError, ConfigProblem, ConnectProblem, MapProblem, MapUpdateProblem, ProtocolProblem,
    RejectProblem, ResultProblem, ServerSaid, UpgradeAnswer, UrlProblem,
};
pub use event::{
    DisconnectReason, ErrorKind, Event, Frame, FrameResult, LostReason, Roughness, ServerInfo,
    StreamMap,
};
pub use session::{Events, FrameSender, Session};
