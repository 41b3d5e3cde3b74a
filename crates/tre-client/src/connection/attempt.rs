//! One connection attempt: the readiness check (if asked), the WebSocket handshake with its
//! TLS and API key, and the Hello answered by Ready; each step within the connect timeout, and
//! each failure told apart as worth retrying or not.

use std::future::Future;
use std::sync::Arc;
use std::time::Duration;

use futures_util::{SinkExt, StreamExt};
use tokio_tungstenite::tungstenite::{self, Message};

use super::{Shared, Ws};
use crate::error::{
    ConfigProblem, ConnectProblem, ProtocolProblem, RejectProblem, ServerSaid, UpgradeAnswer,
};
use crate::event::{Event, ServerInfo};
use crate::proto::{self, Incoming};
use crate::ClientError;

/// One connection attempt: readiness (if asked), WebSocket handshake, Hello → Ready.
pub(super) async fn attempt(shared: Arc<Shared>) -> Result<(Ws, ServerInfo), ClientError> {
    let limit = shared.cfg.connect_timeout;
    if let Some(http) = &shared.http {
        within(
            limit,
            "the readiness check",
            check_ready(http, &shared.endpoints.readyz),
        )
        .await??;
    }
    let url = shared.endpoints.stream.as_str();
    let mut request = tungstenite::client::IntoClientRequest::into_client_request(url)
        .map_err(|e| handshake_error(url, e))?;
    if let Some(key) = &shared.cfg.api_key {
        request
            .headers_mut()
            .insert(tungstenite::http::header::AUTHORIZATION, bearer(key)?);
    }
    let connector = shared.tls.clone().map(tokio_tungstenite::Connector::Rustls);
    let handshake =
        tokio_tungstenite::connect_async_tls_with_config(request, None, true, connector);
    let (mut ws, _) = within(limit, "the WebSocket handshake", handshake)
        .await?
        .map_err(|e| handshake_error(url, e))?;
    let connect = |e| ClientError::Connect {
        url: url.to_owned(),
        reason: ConnectProblem::WebSocket(e),
    };
    ws.send(Message::Binary(shared.hello.clone().into()))
        .await
        .map_err(connect)?;
    let info = within(limit, "Hello → Ready", await_ready(&mut ws, url)).await??;
    Ok((ws, info))
}

/// `fut`, or [`ClientError::Timeout`] after `limit`.
async fn within<T>(
    limit: Duration,
    what: &'static str,
    fut: impl Future<Output = T>,
) -> Result<T, ClientError> {
    tokio::time::timeout(limit, fut)
        .await
        .map_err(|_| ClientError::Timeout {
            what,
            ms: limit.as_millis(),
        })
}

/// The `Authorization: Bearer KEY` value of `key`, marked sensitive.
pub(super) fn bearer(key: &str) -> Result<reqwest::header::HeaderValue, ClientError> {
    let mut v = reqwest::header::HeaderValue::from_str(&format!("Bearer {key}")).map_err(|e| {
        ClientError::BadConfig {
            field: "api_key",
            reason: ConfigProblem::HeaderValue(e),
        }
    })?;
    v.set_sensitive(true);
    Ok(v)
}

/// `GET /readyz`: 200 (or 404: no such route behind a proxy) is ready.
async fn check_ready(http: &reqwest::Client, url: &str) -> Result<(), ClientError> {
    let resp = http
        .get(url)
        .send()
        .await
        .map_err(|e| ClientError::Connect {
            url: url.to_owned(),
            reason: ConnectProblem::Http(e),
        })?;
    match resp.status().as_u16() {
        200 | 404 => Ok(()),
        _ => {
            let status = resp.status();
            // The server's own code and message say why (models loading, the queue full,
            // `--max-connections` reached).
            let body = resp.bytes().await.unwrap_or_default();
            Err(ClientError::NotReady {
                url: url.to_owned(),
                status,
                server: ServerSaid::from_body(&body),
            })
        }
    }
}

/// The first message after the Hello must be Ready; an Error means the Hello was refused.
async fn await_ready(ws: &mut Ws, url: &str) -> Result<ServerInfo, ClientError> {
    while let Some(msg) = ws.next().await {
        let msg = msg.map_err(|e| ClientError::Connect {
            url: url.to_owned(),
            reason: ConnectProblem::WebSocket(e),
        })?;
        match msg {
            Message::Binary(b) => {
                return match proto::decode_server(&b)? {
                    Incoming::Ready(info) => Ok(info),
                    Incoming::Event(Event::Error { code, message, .. }) => {
                        Err(ClientError::HelloRefused { code, message })
                    }
                    other => Err(ClientError::Protocol(ProtocolProblem::ExpectedReady {
                        got: other.name(),
                    })),
                };
            }
            Message::Close(_) => break,
            _ => {}
        }
    }
    Err(ClientError::Connect {
        url: url.to_owned(),
        reason: ConnectProblem::ClosedBeforeReady,
    })
}

/// Handshake failures: HTTP 4xx (but 408 and 429) and bad URLs will not fix themselves.
fn handshake_error(url: &str, e: tungstenite::Error) -> ClientError {
    let url = url.to_owned();
    match e {
        tungstenite::Error::Http(resp) => {
            let body = resp.body().as_deref().unwrap_or_default();
            let answer = UpgradeAnswer {
                status: resp.status(),
                server: ServerSaid::from_body(body),
            };
            if answer.status.is_client_error() && ![408, 429].contains(&answer.status.as_u16()) {
                ClientError::Rejected {
                    url,
                    reason: RejectProblem::Upgrade(answer),
                }
            } else {
                ClientError::Connect {
                    url,
                    reason: ConnectProblem::Upgrade(answer),
                }
            }
        }
        tungstenite::Error::Url(e) => ClientError::Rejected {
            url,
            reason: RejectProblem::Url(e),
        },
        e => ClientError::Connect {
            url,
            reason: ConnectProblem::WebSocket(e),
        },
    }
}
