//! The robot-side client of the WebSocket stream (`GET /v1/stream`): connect with a
//! [`ClientConfig`], send [`Frame`]s, receive [`Event`]s with the roughness decoded to metres;
//! the session paces frames ([`Rate`]), matches answers to frames by sequence number, times
//! frames out, and reconnects with exponential back-off ([`Backoff`]) when the connection
//! drops, reporting the frames that were in flight as lost. [`source`] reads frames from a
//! folder, or from a video file or camera through `ffmpeg`; [`recorder`] streams a source and
//! writes every answer to disk (`tre client`).
//!
//! ```no_run
//! # async fn demo() -> Result<(), tre_client::ClientError> {
//! use tre_client::{ClientConfig, Event, Frame, Rate, Session};
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
//!         other => println!("{other:?}"),
//!     }
//! }
//! # Ok(())
//! # }
//! ```

mod config;
mod connection;
mod error;
mod event;
mod proto;
pub mod recorder;
mod session;
pub mod source;
pub mod tls;

pub use config::{endpoints, Backoff, ClientConfig, Endpoints, Format, Rate};
pub use error::ClientError;
pub use event::{ErrorKind, Event, Frame, FrameResult, LostReason, Roughness, ServerInfo};
pub use session::{unix_us, Events, FrameSender, Session};
