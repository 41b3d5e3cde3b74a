//! HTTP load: `POST /v1/roughness` with one frame per request, in open loop (on a schedule, up
//! to a cap on outstanding requests) or closed loop (clients that wait for each answer).

use std::sync::Arc;
use std::time::Duration;

use reqwest::header::CONTENT_TYPE;
use reqwest::Client;
use tokio::sync::Semaphore;
use tokio::task::JoinSet;
use tokio::time::Instant;

use super::frames::{Frames, LoadFrame};
use super::plan::Plan;
use super::stats::{Outcome, Recorder, Report, RunInfo};
use super::{Load, LoadConfig, LoadError, Target};

/// Longest a connection attempt may take (shorter if the request timeout is).
const CONNECT_TIMEOUT: Duration = Duration::from_secs(5);

/// What one run shares with its request tasks.
struct Shared {
    client: Client,
    url: String,
    frames: Frames,
    plan: Plan,
    rec: Recorder,
}

/// Runs `cfg` over HTTP against `target`.
pub(super) async fn drive(
    cfg: &LoadConfig,
    target: &Target,
    frames: &Frames,
) -> Result<Report, LoadError> {
    let mut headers = reqwest::header::HeaderMap::new();
    if let Some(key) = &cfg.api_key {
        headers.insert(reqwest::header::AUTHORIZATION, super::bearer(key)?);
    }
    let mut builder = Client::builder()
        .default_headers(headers)
        .no_proxy()
        .timeout(cfg.timeout)
        .connect_timeout(cfg.timeout.min(CONNECT_TIMEOUT))
        .tcp_nodelay(true)
        .resolve(&target.host, target.addr);
    if target.tls {
        let tls = tre_client::tls::client_config(cfg.ca_cert.as_deref()).map_err(LoadError::Tls)?;
        builder = builder.use_preconfigured_tls(rustls::ClientConfig::clone(&tls));
    }
    let client = builder.build()?;
    let plan = Plan::new(cfg);
    let shared = Arc::new(Shared {
        client,
        url: match cfg.ask.http_query() {
            q if q.is_empty() => target.roughness_url(),
            q => format!("{}?{q}", target.roughness_url()),
        },
        frames: frames.clone(),
        rec: Recorder::new(plan.measure_from),
        plan,
    });
    let window_s = match cfg.load {
        Load::Open { rate_per_s } => {
            open_loop(&shared, rate_per_s, cfg.max_in_flight).await;
            shared.plan.measured() as f64 / rate_per_s
        }
        Load::Closed => {
            closed_loop(&shared, cfg.connections).await;
            let end = shared.rec.last_done().unwrap_or(shared.plan.measure_from);
            end.saturating_duration_since(shared.plan.measure_from)
                .as_secs_f64()
        }
    };
    let info = RunInfo::new(cfg, shared.url.clone(), frames, &shared.plan);
    Ok(shared.rec.report(info, window_s))
}

/// Sends request `i` at its intended time whatever the answers do; latency counts from the
/// intended time. Beyond `max_in_flight` outstanding, a due request is `client_saturated`.
async fn open_loop(shared: &Arc<Shared>, rate_per_s: f64, max_in_flight: usize) {
    let permits = Arc::new(Semaphore::new(max_in_flight));
    let mut tasks = JoinSet::new();
    for i in 0u64.. {
        let intended = shared.plan.intended(i, rate_per_s);
        if shared.plan.admit(intended).is_none() {
            break;
        }
        tokio::time::sleep_until(intended).await;
        while tasks.try_join_next().is_some() {}
        let Ok(permit) = permits.clone().try_acquire_owned() else {
            shared
                .rec
                .record(intended, intended, Outcome::ClientSaturated);
            continue;
        };
        let shared = shared.clone();
        tasks.spawn(async move {
            let outcome = send(&shared.client, &shared.url, shared.frames.get(i)).await;
            shared.rec.record(intended, Instant::now(), outcome);
            drop(permit);
        });
    }
    while tasks.join_next().await.is_some() {}
}

/// `connections` clients, each sending its next request when the answer to the previous one
/// is back.
async fn closed_loop(shared: &Arc<Shared>, connections: usize) {
    let mut tasks = JoinSet::new();
    for c in 0..connections as u64 {
        let shared = shared.clone();
        tasks.spawn(async move {
            // The run starts at `t0`: a request sent before it would be taken for warm-up
            // while the window counted its time.
            tokio::time::sleep_until(shared.plan.t0).await;
            let mut i = c;
            loop {
                let sent = Instant::now();
                if shared.plan.admit(sent).is_none() {
                    break;
                }
                let outcome = send(&shared.client, &shared.url, shared.frames.get(i)).await;
                shared.rec.record(sent, Instant::now(), outcome);
                i += connections as u64;
            }
        });
    }
    while tasks.join_next().await.is_some() {}
}

/// Sends one frame and reads the whole answer.
async fn send(client: &Client, url: &str, frame: &LoadFrame) -> Outcome {
    let sent = client
        .post(url)
        .header(CONTENT_TYPE, frame.content_type)
        .body(frame.bytes.clone())
        .send()
        .await;
    let resp = match sent {
        Ok(r) => r,
        Err(e) => return Outcome::Error(error_kind(&e)),
    };
    let status = resp.status().as_u16();
    let is_map = resp.headers().contains_key(ROUGHNESS_HEADER);
    match resp.bytes().await {
        Ok(body) => classify(status, is_map, &body),
        Err(e) => Outcome::Error(error_kind(&e)),
    }
}

/// The header every roughness map from `tre serve` carries.
const ROUGHNESS_HEADER: &str = "x-roughness-scale-m";

/// The outcome of an answer: a 2xx roughness map (`is_map`: it has the `X-Roughness-Scale-M`
/// header) ok, any other 2xx an error `not a roughness map` (a server that is not `tre serve`
/// must not pass for a fast one), 429/503 refused (by the body's error code), else an error
/// named `http STATUS CODE`.
pub(crate) fn classify(status: u16, is_map: bool, body: &[u8]) -> Outcome {
    let code = || error_code(body).unwrap_or_else(|| "-".into());
    match status {
        200..=299 if is_map => Outcome::Ok,
        200..=299 => Outcome::Error(format!("http {status} not a roughness map")),
        429 | 503 => Outcome::Refused(code()),
        _ => Outcome::Error(format!("http {status} {}", code())),
    }
}

/// `error.code` of a JSON error body.
fn error_code(body: &[u8]) -> Option<String> {
    let v: serde_json::Value = serde_json::from_slice(body).ok()?;
    Some(v.get("error")?.get("code")?.as_str()?.to_owned())
}

/// Kind of a client-side failure: `timeout`, `connect`, `body` or `request`.
fn error_kind(e: &reqwest::Error) -> String {
    if e.is_timeout() {
        "timeout"
    } else if e.is_connect() {
        "connect"
    } else if e.is_body() || e.is_decode() {
        "body"
    } else {
        "request"
    }
    .into()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn answers_are_classified_by_status_and_code() {
        let body = br#"{"error":{"code":"overloaded","message":"queue full"}}"#;
        assert_eq!(classify(200, true, b"png"), Outcome::Ok);
        assert_eq!(
            classify(200, false, b"<html>hello</html>"),
            Outcome::Error("http 200 not a roughness map".into())
        );
        assert_eq!(
            classify(503, false, body),
            Outcome::Refused("overloaded".into())
        );
        assert_eq!(classify(429, false, b"?"), Outcome::Refused("-".into()));
        let bad = br#"{"error":{"code":"bad_image","message":"truncated"}}"#;
        assert_eq!(
            classify(422, false, bad),
            Outcome::Error("http 422 bad_image".into())
        );
        assert_eq!(
            classify(500, false, b""),
            Outcome::Error("http 500 -".into())
        );
    }
}
