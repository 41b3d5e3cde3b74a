//! `GET /v1/stream` on a real `tre serve` over loopback: results equal `tre infer`, latest
//! frame wins with drops reported, garbage and oversize messages are errors that keep the
//! stream open, and vanishing clients do not hurt the server (memory over a sustained stream:
//! `benches/stream_memory.rs`).
#![allow(clippy::unwrap_used)] // Test helpers fail loudly by design.

use crate::common;

use std::time::Duration;

use common::stream::{connect, frame, handshake, next, send, Ws};
use common::{get, infer_png16, png16_values, real, rt, Server};
use futures_util::{SinkExt, StreamExt};
use prost::Message as _;
use tokio_tungstenite::tungstenite::Message;
use tre::proto::v1 as pb;

mod bad_messages;
mod hello;
mod lifecycle;
mod limits;
mod map;
