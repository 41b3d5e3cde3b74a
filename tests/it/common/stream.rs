//! A client's end of `GET /v1/stream` for the tests and benches: connect, the Hello, frames,
//! and the server's next message.

use std::time::Duration;

use futures_util::{SinkExt, StreamExt};
use prost::Message as _;
use tokio_tungstenite::tungstenite::Message;
use tre::proto::v1 as pb;

use super::Server;

/// A WebSocket to the server.
pub(crate) type Ws =
    tokio_tungstenite::WebSocketStream<tokio_tungstenite::MaybeTlsStream<tokio::net::TcpStream>>;

/// [`super::rt`], here too for `benches/stream_memory.rs`, which takes its stream helpers from
/// this module.
#[allow(unused_imports)] // Only that bench takes it from here.
pub(crate) use super::rt;

/// Opens `/v1/stream` on `server`.
pub(crate) async fn connect(server: &Server) -> Ws {
    let url = format!("ws://{}/v1/stream", server.addr);
    tokio_tungstenite::connect_async(url).await.unwrap().0
}

/// A Hello asking for `format` in `mode`.
fn hello(format: pb::Format, mode: pb::Mode) -> Vec<u8> {
    pb::ClientMessage {
        msg: Some(pb::client_message::Msg::Hello(pb::Hello {
            format: format as i32,
            mode: mode as i32,
            ..Default::default()
        })),
    }
    .encode_to_vec()
}

/// A frame of encoded image bytes with sequence number `sequence`.
pub(crate) fn frame(sequence: u64, image: Vec<u8>) -> Vec<u8> {
    pb::ClientMessage {
        msg: Some(pb::client_message::Msg::Frame(pb::Frame {
            sequence,
            timestamp_us: 1_000 + sequence as i64,
            image,
            ..Default::default()
        })),
    }
    .encode_to_vec()
}

/// Sends a binary message.
pub(crate) async fn send(ws: &mut Ws, bytes: Vec<u8>) {
    ws.send(Message::Binary(bytes.into())).await.unwrap();
}

/// The next server message (pings skipped).
pub(crate) async fn next(ws: &mut Ws) -> pb::server_message::Msg {
    loop {
        let msg = tokio::time::timeout(Duration::from_secs(60), ws.next())
            .await
            .expect("no message within 60 s")
            .expect("stream ended")
            .expect("stream failed");
        match msg {
            Message::Binary(b) => return pb::ServerMessage::decode(&b[..]).unwrap().msg.unwrap(),
            Message::Ping(_) | Message::Pong(_) => continue,
            other => panic!("unexpected {other:?}"),
        }
    }
}

/// Sends the Hello and expects a Ready that lists the depth net.
pub(crate) async fn handshake(ws: &mut Ws, format: pb::Format, mode: pb::Mode) {
    send(ws, hello(format, mode)).await;
    match next(ws).await {
        pb::server_message::Msg::Ready(r) => assert!(r.models.iter().any(|m| m == "depth_net")),
        other => panic!("expected Ready, got {other:?}"),
    }
}
