//! HTTP handlers: `POST /v1/roughness` and the operational endpoints (`/healthz`, `/readyz`,
//! `/metrics`, `/v1/models`, `/openapi.json`, the demo page at `/`).

use std::sync::Arc;
use std::time::Instant;

use axum::body::{Body, Bytes, HttpBody};
use axum::extract::{FromRequest, Multipart, Query, Request, State};
use axum::http::{header, HeaderMap, HeaderValue, StatusCode};
use axum::response::{IntoResponse, Response};
use http_body_util::BodyExt;

use super::error::{ApiError, ImagePart, RequestError};
use super::metrics::Gauges;
use super::openapi::{Binary, ErrorResponse, Guarded, JsonObject, RoughnessForm};
use super::query::RoughnessQuery;
use super::request::{
    image_header, strict_camera, DecodeLimits, FrameReply, FrameRequest, SCALE_M,
};
use super::{AppState, OVERSIZE_READ_FACTOR};
use tre_proto::ErrorCode;

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
                    did not give, comma-separated keys among intrinsics, depth_scale, mounting \
                    and mode; absent when nothing was assumed."),
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
            .map_err(|rejection| RequestError::Query {
                query: q.to_owned(),
                rejection,
            }),
    };
    // The body is read before a bad query is answered: a client still sending it would
    // otherwise meet a closed connection instead of the error.
    let mut frame = tokio::time::timeout(body_timeout, read_body(app, req))
        .await
        .map_err(|_| RequestError::BodyTimeout {
            timeout: body_timeout,
        })??;
    let timeout = app.cfg.request_timeout;
    let deadline = tokio::time::Instant::now() + timeout;
    let max_concurrent = app.cfg.max_concurrent;
    let permit = app.concurrency.clone().try_acquire_owned();
    let _permit = permit.map_err(|_| RequestError::TooManyRequests { max_concurrent })?;
    let query = query?;
    frame.options = query.options()?;
    match (&frame.camera, query.camera(app.cfg.decode_limits())?) {
        (Some(_), Some(_)) => return Err(RequestError::CameraTwice.into()),
        (None, from_query) => frame.camera = from_query,
        (Some(_), None) => {}
    }
    check_shapes(&frame, app.cfg.decode_limits())?;
    let rx = app.workers.submit(frame)?;
    match tokio::time::timeout_at(deadline, rx).await {
        Ok(Ok((result, _queued))) => result,
        Ok(Err(_)) => Err(RequestError::WorkerStopped.into()),
        Err(_) => Err(RequestError::Timeout { timeout }.into()),
    }
}

/// The images' shapes from their headers, before the frame takes a place in the queue: a
/// frame beyond the limits is refused at once rather than when a worker reaches it. (The
/// worker checks again, and checks `.npy` depth, whose shape comes with its parsing.)
pub(crate) fn check_shapes(frame: &FrameRequest, limits: DecodeLimits) -> Result<(), RequestError> {
    if let Some(rgb) = &frame.rgb {
        image_header(ImagePart::Rgb, rgb, limits)?;
    }
    if let Some(depth) = frame
        .depth
        .as_ref()
        .filter(|d| !d.starts_with(b"\x93NUMPY"))
    {
        match image_header(ImagePart::Depth, depth, limits) {
            Err(e) if e.is_over_limit() => return Err(e),
            // Other depth errors are answered by the worker, saying what depth may be.
            _ => {}
        }
    }
    Ok(())
}

/// Reads the body within the byte limit: a bare image, or multipart with `rgb`, `depth`,
/// `camera`.
async fn read_body(app: &AppState, req: Request) -> Result<FrameRequest, RequestError> {
    let content_type = req
        .headers()
        .get(header::CONTENT_TYPE)
        .and_then(|v| v.to_str().ok())
        .unwrap_or("")
        .to_owned();
    let pace = BodyPace::new(app.cfg.min_body_rate);
    let bytes = read_within(req.into_body(), app.cfg.max_body_bytes, pace).await?;
    parse_body(&content_type, bytes, app.cfg.decode_limits()).await
}

/// The frame a body of `content_type` carries: a bare image, or multipart with `rgb`, `depth`,
/// `camera` (the camera checked with [`strict_camera`]). The images are not decoded here.
pub(crate) async fn parse_body(
    content_type: &str,
    bytes: Bytes,
    limits: DecodeLimits,
) -> Result<FrameRequest, RequestError> {
    // The boundary keeps its case (browsers' mix both); only the type is compared lowercase.
    let lower = content_type.to_ascii_lowercase();
    if lower.starts_with("multipart/form-data") {
        let req = Request::builder()
            .header(header::CONTENT_TYPE, content_type)
            .body(Body::from(bytes))
            .map_err(RequestError::MultipartHeader)?;
        let multipart = Multipart::from_request(req, &())
            .await
            .map_err(RequestError::MultipartBoundary)?;
        return read_multipart(multipart, limits).await;
    }
    let image_type = [
        "",
        "image/png",
        "image/jpeg",
        "image/jpg",
        "application/octet-stream",
    ];
    let essence = lower.split(';').next().unwrap_or("").trim();
    if !image_type.contains(&essence) {
        return Err(RequestError::ContentType {
            essence: essence.to_owned(),
        });
    }
    Ok(FrameRequest {
        rgb: Some(bytes.to_vec()),
        ..FrameRequest::default()
    })
}

/// The body, if it has at most `limit` bytes and arrives at `pace`; a 413 otherwise, once the
/// rest has been read (up to [`OVERSIZE_READ_FACTOR`] × `limit`) and discarded, or at once when
/// the declared length is beyond that; a 408 when it falls below the pace.
async fn read_within(
    mut body: Body,
    limit: usize,
    mut pace: BodyPace,
) -> Result<Bytes, RequestError> {
    let most = limit.saturating_mul(OVERSIZE_READ_FACTOR);
    let too_large = || RequestError::BodyTooLarge { limit };
    // The declared length, if any, sizes the buffer once (never beyond the limit).
    let declared = usize::try_from(body.size_hint().lower()).unwrap_or(usize::MAX);
    if declared > most {
        return Err(too_large());
    }
    let mut kept = Vec::with_capacity(declared.min(limit));
    let mut seen = 0usize;
    while seen <= most {
        let next = match pace.deadline() {
            None => body.frame().await,
            Some(at) => match tokio::time::timeout_at(at, body.frame()).await {
                Ok(next) => next,
                Err(_) => {
                    pace.check(0, tokio::time::Instant::now())?;
                    continue;
                }
            },
        };
        let Some(frame) = next else {
            break;
        };
        let frame = frame.map_err(RequestError::ReadBody)?;
        let Ok(data) = frame.into_data() else {
            continue;
        };
        pace.check(data.len(), tokio::time::Instant::now())?;
        seen = seen.saturating_add(data.len());
        if seen <= limit {
            kept.extend_from_slice(&data);
        }
    }
    if seen > limit {
        return Err(too_large());
    }
    Ok(Bytes::from(kept))
}

/// Window over which a body's rate is averaged (`--min-body-rate`); the first one is the grace
/// a client has before its rate counts. One window for HTTP bodies and stream messages.
pub(crate) use super::pace::PACE_WINDOW as BODY_RATE_WINDOW;

/// The pace a body must keep: on average at least `--min-body-rate` bytes a second over each
/// [`BODY_RATE_WINDOW`] from the headers on (a tumbling window: a body sent quickly and then
/// stopped is caught one window later, not after its earlier bytes have been used up).
#[derive(Debug, Clone, Copy)]
struct BodyPace {
    /// Bytes a second; 0: no pace.
    min_bytes_per_s: u64,
    /// Start of the current window.
    since: tokio::time::Instant,
    /// Bytes in it.
    bytes: usize,
}

impl BodyPace {
    fn new(min_bytes_per_s: u64) -> Self {
        Self {
            min_bytes_per_s,
            since: tokio::time::Instant::now(),
            bytes: 0,
        }
    }

    /// When the current window ends; `None` without a pace.
    fn deadline(&self) -> Option<tokio::time::Instant> {
        (self.min_bytes_per_s > 0).then(|| self.since + BODY_RATE_WINDOW)
    }

    /// Counts `n` bytes arrived at `now`; at the end of a window, a 408 if it held too few,
    /// else the next window starts.
    fn check(&mut self, n: usize, now: tokio::time::Instant) -> Result<(), RequestError> {
        self.bytes = self.bytes.saturating_add(n);
        if self.deadline().is_none_or(|end| now < end) {
            return Ok(());
        }
        let secs = (now - self.since).as_secs_f64();
        let rate = self.bytes as f64 / secs;
        if rate < self.min_bytes_per_s as f64 {
            return Err(RequestError::BodyTooSlow {
                rate,
                secs,
                min_bytes_per_s: self.min_bytes_per_s,
            });
        }
        self.since = now;
        self.bytes = 0;
        Ok(())
    }
}

async fn read_multipart(
    mut m: Multipart,
    limits: DecodeLimits,
) -> Result<FrameRequest, RequestError> {
    let mut frame = FrameRequest::default();
    while let Some(field) = m.next_field().await.map_err(RequestError::Multipart)? {
        let name = field.name().unwrap_or("").to_owned();
        let data = match field.bytes().await {
            Ok(data) => data,
            Err(source) => return Err(RequestError::MultipartField { name, source }),
        };
        match name.as_str() {
            "rgb" => set_once(&mut frame.rgb, &name, || Ok(data.to_vec()))?,
            "depth" => set_once(&mut frame.depth, &name, || Ok(data.to_vec()))?,
            "camera" => set_once(&mut frame.camera, &name, || strict_camera(&data, limits))?,
            _ => return Err(RequestError::UnknownPart { name }),
        }
    }
    if frame.rgb.is_none() && frame.depth.is_none() {
        return Err(RequestError::NoImagePart);
    }
    Ok(frame)
}

/// Fills the slot of multipart part `name` with `value()`, unless the part came before.
fn set_once<T>(
    slot: &mut Option<T>,
    name: &str,
    value: impl FnOnce() -> Result<T, RequestError>,
) -> Result<(), RequestError> {
    if slot.is_some() {
        return Err(RequestError::PartTwice {
            name: name.to_owned(),
        });
    }
    *slot = Some(value()?);
    Ok(())
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
    ApiError::from(RequestError::NoRoute { path }).into_response()
}

/// A known path with another method: a JSON 405.
pub(crate) async fn method_not_allowed(
    method: axum::http::Method,
    uri: axum::http::Uri,
) -> Response {
    let path = uri.path().to_owned();
    ApiError::from(RequestError::MethodNotAllowed { method, path }).into_response()
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
        Some(None) => ApiError::from(RequestError::EmptyStreamMap { stream: id }).into_response(),
        None => ApiError::from(RequestError::NoStreamMap { stream: id }).into_response(),
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
        ApiError::from(RequestError::NotReady).into_response()
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
