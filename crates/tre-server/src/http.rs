//! HTTP handlers: `POST /v1/roughness` and the operational endpoints (`/healthz`, `/readyz`,
//! `/metrics`, `/v1/models`, `/openapi.json`, the demo page at `/`).

use std::sync::Arc;
use std::time::Instant;

use axum::extract::{Query, Request, State};
use axum::http::{header, HeaderMap, HeaderValue, StatusCode};
use axum::response::{IntoResponse, Response};

use super::error::{ApiError, BodyError, LimitError, ServiceError};
use super::metrics::Gauges;
use super::openapi::{Binary, ErrorResponse, Guarded, JsonObject, RoughnessForm};
use super::query::RoughnessQuery;
use super::request::{FrameReply, SCALE_M};
use super::AppState;
use tre_proto::ErrorCode;

mod body;

pub(crate) use body::check_shapes;
#[cfg(any(test, feature = "fuzzing"))]
pub(crate) use body::parse_body;
use body::read_body;

/// `POST /v1/roughness`.
#[utoipa::path(
    post,
    path = "/v1/roughness",
    summary = "Roughness of one frame",
    description = "A query parameter not listed here is refused with 400 bad_request.",
    params(RoughnessQuery),
    request_body(
        description = "The frame: a bare PNG or JPEG image, or multipart/form-data with its parts. \
            As application/octet-stream, a PNG or JPEG, told apart by its first bytes; so is a \
            body with no Content-Type.",
        content(
            (inline(Binary) = "image/png"),
            (inline(Binary) = "image/jpeg"),
            (inline(Binary) = "image/jpg"),
            (inline(Binary) = "application/octet-stream"),
            (inline(RoughnessForm) = "multipart/form-data"),
        ),
    ),
    responses(
        (status = 200, description = "The roughness map, the size of the input frame.",
            headers(
                ("X-Roughness-Scale-M" = f64, description = "Metres per unit of png16."),
                ("X-Image-Width" = u32),
                ("X-Image-Height" = u32),
                ("X-Working-Size" = String, description = "WxH the stages ran at."),
                ("Server-Timing" = String, description = "Wall time per stage, ms."),
                ("X-Tre-Mode" = String, description = "The mode that ran: rgb, rgbd or \
                    geometric."),
                ("X-Tre-Gravity" = String, description = "Where gravity came from, with its \
                    figures: `stated; pitch_deg=…; roll_deg=…; height_m=…`, `estimated; …; \
                    support=…` or `unknown; reason=\"…\"`."),
                ("X-Tre-Assumed" = String, description = "What stood in for what the request \
                    did not give, comma-separated keys among intrinsics, depth_scale, mounting, \
                    sensor and mode; absent when nothing was assumed."),
                ("Warning" = String, description = "Repeated: one `199 tre \"…\"` (RFC 7234) \
                    per assumption and per input that looks wrong or leaves the answer mostly \
                    unknown, in words."),
            ),
            content(
                (inline(Binary) = "image/png"),
                (inline(Binary) = "application/octet-stream"),
                (inline(Binary) = "multipart/mixed"),
            ),
        ),
        (status = 400, response = ErrorResponse),
        Guarded,
        (status = 408, response = ErrorResponse),
        (status = 413, response = ErrorResponse),
        (status = 415, response = ErrorResponse),
        (status = 422, response = ErrorResponse),
        (status = 429, response = ErrorResponse),
        (status = 500, response = ErrorResponse),
    ),
)]
pub(crate) async fn roughness(State(app): State<Arc<AppState>>, req: Request) -> Response {
    let start = Instant::now();
    match roughness_inner(&app, req).await {
        Ok(reply) => {
            app.metrics
                .request("roughness", "ok", Some(start.elapsed()));
            reply_response(reply)
        }
        Err(e) => {
            app.metrics.request("roughness", e.code.as_str(), None);
            // Refusals are logged, rate-limited, by the access layer.
            if e.code == ErrorCode::Internal {
                tracing::error!(error = %e.message, "request failed");
            }
            e.into_response()
        }
    }
}

async fn roughness_inner(app: &AppState, req: Request) -> Result<FrameReply, ApiError> {
    // The body has its own deadline (408), and a request takes a `--max-concurrent` place only
    // once its body is in: clients still uploading, however slowly, hold none of the places
    // that ready requests need (they are bounded by `--max-connections` and this deadline).
    let body_timeout = app.cfg.body_timeout;
    let query = match req.uri().query() {
        None => Ok(RoughnessQuery::default()),
        Some(q) => Query::<RoughnessQuery>::try_from_uri(req.uri())
            .map(|Query(q)| q)
            .map_err(|rejection| BodyError::Query {
                query: q.to_owned(),
                rejection,
            }),
    };
    // The body is read before a bad query is answered: a client still sending it would
    // otherwise meet a closed connection instead of the error.
    let mut frame = tokio::time::timeout(body_timeout, read_body(app, req))
        .await
        .map_err(|_| LimitError::BodyTimeout {
            timeout: body_timeout,
        })??;
    let timeout = app.cfg.request_timeout;
    let deadline = tokio::time::Instant::now() + timeout;
    let max_concurrent = app.cfg.max_concurrent;
    let permit = app.concurrency.clone().try_acquire_owned();
    let _permit = permit.map_err(|_| LimitError::TooManyRequests { max_concurrent })?;
    let query = query?;
    frame.options = query.options()?;
    match (&frame.camera, query.camera(app.cfg.decode_limits())?) {
        (Some(_), Some(_)) => return Err(BodyError::CameraTwice.into()),
        (None, from_query) => frame.camera = from_query,
        (Some(_), None) => {}
    }
    check_shapes(&frame, app.cfg.decode_limits())?;
    let rx = app.workers.submit(frame)?;
    match tokio::time::timeout_at(deadline, rx).await {
        Ok(Ok((result, _queued))) => result,
        Ok(Err(_)) => Err(ServiceError::WorkerStopped.into()),
        Err(_) => Err(ServiceError::Timeout { timeout }.into()),
    }
}

/// `Server-Timing` value: one entry per stage, milliseconds.
pub(crate) fn server_timing(reply: &FrameReply) -> String {
    reply
        .timings
        .iter()
        .map(|(stage, d)| format!("{stage};dur={:.2}", d.as_secs_f64() * 1e3))
        .collect::<Vec<_>>()
        .join(", ")
}

/// `text` as a header value can carry it: visible ASCII (`°` written `deg`, other characters
/// dropped).
fn header_text(text: &str) -> String {
    text.replace('°', " deg")
        .chars()
        .filter(|c| c.is_ascii() && !c.is_ascii_control())
        .collect()
}

/// Sets header `name` to `value` when it can be a header value.
fn set(headers: &mut HeaderMap, name: &'static str, value: String) {
    if let Ok(v) = HeaderValue::from_str(&value) {
        headers.insert(name, v);
    }
}

/// The headers of an answer: the map's scale and sizes, the stage times, and what ran and
/// what it assumed ([`FrameReply::mode`], [`FrameReply::gravity`], [`FrameReply::assumed`]).
fn reply_headers(reply: &FrameReply) -> HeaderMap {
    let mut headers = HeaderMap::new();
    set(&mut headers, "x-roughness-scale-m", SCALE_M.to_string());
    set(&mut headers, "x-image-width", reply.size.0.to_string());
    set(&mut headers, "x-image-height", reply.size.1.to_string());
    let (w, h) = reply.working_size;
    set(&mut headers, "x-working-size", format!("{w}x{h}"));
    set(&mut headers, "server-timing", server_timing(reply));
    set(&mut headers, "x-tre-mode", reply.mode.to_string());
    let gravity = header_text(&reply.gravity.to_string());
    set(&mut headers, "x-tre-gravity", gravity);
    if !reply.assumed.is_empty() {
        let keys: Vec<&str> = reply.assumed.iter().map(|a| a.key()).collect();
        set(&mut headers, "x-tre-assumed", keys.join(", "));
    }
    // RFC 7234's Warning header, one per assumption and one per implausible input, in words
    // (code 199: miscellaneous).
    let said = reply.assumed.iter().map(ToString::to_string);
    for words in said.chain(reply.warnings.iter().cloned()) {
        let words = header_text(&words).replace('"', "'");
        if let Ok(v) = HeaderValue::from_str(&format!("199 tre \"{words}\"")) {
            headers.append("warning", v);
        }
    }
    headers
}

fn reply_response(reply: FrameReply) -> Response {
    let mut headers = reply_headers(&reply);
    if reply.extras.is_empty() {
        set(
            &mut headers,
            "content-type",
            reply.format.content_type().into(),
        );
        return (StatusCode::OK, headers, reply.roughness).into_response();
    }
    let boundary = format!(
        "tre-{:016x}",
        tre_core::geometry::hash::splitmix64(reply.roughness.len() as u64 ^ 0x5eed)
    );
    set(
        &mut headers,
        "content-type",
        format!("multipart/mixed; boundary={boundary}"),
    );
    let name = format!("roughness.{}", reply.format.extension());
    let mut body = Vec::new();
    let mut part = |field: &str, file: &str, ct: &str, bytes: &[u8]| {
        body.extend_from_slice(format!("--{boundary}\r\nContent-Disposition: attachment; name=\"{field}\"; filename=\"{file}\"\r\nContent-Type: {ct}\r\n\r\n").as_bytes());
        body.extend_from_slice(bytes);
        body.extend_from_slice(b"\r\n");
    };
    part(
        "roughness",
        &name,
        reply.format.content_type(),
        &reply.roughness,
    );
    for p in &reply.extras {
        part(p.name, p.filename, p.content_type, &p.bytes);
    }
    body.extend_from_slice(format!("--{boundary}--\r\n").as_bytes());
    (StatusCode::OK, headers, body).into_response()
}

/// Any other path: a JSON 404.
pub(crate) async fn not_found(uri: axum::http::Uri) -> Response {
    let path = uri.path().to_owned();
    ApiError::from(ServiceError::NoRoute { path }).into_response()
}

/// A known path with another method: a JSON 405.
pub(crate) async fn method_not_allowed(
    method: axum::http::Method,
    uri: axum::http::Uri,
) -> Response {
    let path = uri.path().to_owned();
    ApiError::from(ServiceError::MethodNotAllowed { method, path }).into_response()
}

/// `GET /v1/streams/{id}/map`: the grid map of an open stream whose Hello asked for one.
#[utoipa::path(
    get,
    path = "/v1/streams/{id}/map",
    summary = "The current grid map of a stream",
    description = "The map of the stream whose Ready carried this stream_id, as a \
        roughness.v1.MapUpdate protobuf message (docs/map.md), while the stream is open.",
    params(("id" = String, Path, description = "The stream's id (Ready.stream_id).")),
    responses(
        (status = 200, description = "The map (a MapUpdate message).",
            content((inline(Binary) = "application/x-protobuf"))),
        (status = 404, response = ErrorResponse),
    ),
)]
pub(crate) async fn stream_map(
    State(app): State<Arc<AppState>>,
    axum::extract::Path(id): axum::extract::Path<String>,
) -> Response {
    let update = app.maps.get(&id).map(|m| {
        m.lock()
            .unwrap_or_else(std::sync::PoisonError::into_inner)
            .update()
    });
    match update {
        Some(Some(u)) => {
            use prost::Message as _;
            (
                StatusCode::OK,
                [(header::CONTENT_TYPE, "application/x-protobuf")],
                u.encode_to_vec(),
            )
                .into_response()
        }
        Some(None) => ApiError::from(ServiceError::EmptyStreamMap { stream: id }).into_response(),
        None => ApiError::from(ServiceError::NoStreamMap { stream: id }).into_response(),
    }
}

/// `GET /healthz`: the process is up.
#[utoipa::path(
    get,
    path = "/healthz",
    summary = "Liveness: the process is up",
    responses(
        (status = 200, description = "Up", body = inline(JsonObject)),
        (status = 503, response = ErrorResponse),
    ),
)]
pub(crate) async fn healthz() -> impl IntoResponse {
    (
        StatusCode::OK,
        [(header::CONTENT_TYPE, "application/json")],
        r#"{"status":"ok"}"#,
    )
}

/// `GET /readyz`: 200 once every worker has loaded and warmed up its models.
#[utoipa::path(
    get,
    path = "/readyz",
    summary = "Readiness: every worker has loaded and warmed up the models",
    responses(
        (status = 200, description = "Ready", body = inline(JsonObject)),
        (status = 503, response = ErrorResponse),
    ),
)]
pub(crate) async fn readyz(State(app): State<Arc<AppState>>) -> Response {
    if app.workers.ready() {
        (
            StatusCode::OK,
            [(header::CONTENT_TYPE, "application/json")],
            r#"{"status":"ready"}"#,
        )
            .into_response()
    } else {
        ApiError::from(ServiceError::NotReady).into_response()
    }
}

/// `GET /metrics`: Prometheus text.
#[utoipa::path(
    get,
    path = "/metrics",
    summary = "Prometheus metrics",
    responses(
        (status = 200, description = "Text exposition format", body = String, content_type = "text/plain"),
        Guarded,
    ),
)]
pub(crate) async fn metrics(State(app): State<Arc<AppState>>) -> impl IntoResponse {
    let text = app.metrics.render(Gauges {
        queue_depth: app.workers.queue_depth(),
        queue_capacity: app.workers.capacity(),
        workers: app.workers.count(),
        ready: app.workers.ready(),
    });
    ([(header::CONTENT_TYPE, "text/plain; version=0.0.4")], text)
}

/// `GET /v1/models`: the manifest the workers loaded.
#[utoipa::path(
    get,
    path = "/v1/models",
    summary = "The model manifest the service runs",
    responses(
        (status = 200, description = "models/manifest.json", body = inline(JsonObject)),
        Guarded,
    ),
)]
pub(crate) async fn models(State(app): State<Arc<AppState>>) -> impl IntoResponse {
    (
        [(header::CONTENT_TYPE, "application/json")],
        app.manifest_json.clone(),
    )
}

/// `GET /openapi.json`: the document generated from these handlers ([`super::openapi`]).
#[utoipa::path(
    get,
    path = "/openapi.json",
    summary = "This document",
    responses(
        (status = 200, description = "OpenAPI 3.0", body = inline(JsonObject)),
        Guarded,
    ),
)]
pub(crate) async fn openapi() -> impl IntoResponse {
    (
        [(header::CONTENT_TYPE, "application/json")],
        super::openapi::document_json(),
    )
}

/// The demo page.
pub(crate) const DEMO_PAGE: &str = include_str!("demo/index.html");

/// `GET /`: the demo page.
#[utoipa::path(
    get,
    path = "/",
    summary = "Demo page",
    responses(
        (status = 200, description = "HTML", body = String, content_type = "text/html"),
        Guarded,
    ),
)]
pub(crate) async fn demo() -> impl IntoResponse {
    (
        [(header::CONTENT_TYPE, "text/html; charset=utf-8")],
        DEMO_PAGE,
    )
}

#[cfg(test)]
mod tests;
