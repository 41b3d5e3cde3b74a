//! Who may use the service, and the request id: one layer in front of every route that
//!
//! - gives each request an id (the client's `X-Request-Id` when it is short and plain, else
//!   the server's own), sent back in `X-Request-Id` and written beside every refusal;
//! - refuses browser origins not on `--allow-origin` (403 `forbidden`; a page served by the
//!   server itself is same-origin and allowed), answers CORS preflights of allowed ones, and
//!   sets `Access-Control-Allow-Origin` for them only;
//! - with `--api-key`, wants `Authorization: Bearer KEY` on every route and the stream upgrade
//!   except `/healthz` and `/readyz` (401 `unauthorized` otherwise);
//! - logs every refusal, rate-limited ([`super::refusals`]).

use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::Arc;

use axum::extract::{Request, State};
use axum::http::{header, HeaderMap, HeaderValue, Method, StatusCode};
use axum::middleware::Next;
use axum::response::{IntoResponse, Response};

use super::error::{ApiError, Refused, RequestError, ServiceError};
use super::AppState;
use tre_proto::ErrorCode;

/// The id of a request, as logged and sent back in `X-Request-Id`.
#[derive(Debug, Clone)]
pub(crate) struct RequestId(pub String);

/// Routes that answer without a key or an origin check: probes of orchestrators.
const OPEN_PATHS: [&str; 2] = ["/healthz", "/readyz"];
/// Response headers a page of an allowed origin may read.
const EXPOSED: &str = "server-timing, x-roughness-scale-m, x-image-width, x-image-height, \
     x-working-size, x-request-id, x-tre-mode, x-tre-gravity, x-tre-assumed, warning";

/// Source of the server's own request ids.
static NEXT_ID: AtomicU64 = AtomicU64::new(1);

/// The layer's function, for `axum::middleware::from_fn_with_state`.
pub(crate) async fn guard(
    State(app): State<Arc<AppState>>,
    mut req: Request,
    next: Next,
) -> Response {
    let id = request_id(req.headers());
    let path = req.uri().path().to_owned();
    let origin = req
        .headers()
        .get(header::ORIGIN)
        .and_then(|o| o.to_str().ok())
        .map(str::to_owned);
    let cross = origin.as_deref().filter(|o| !same_origin(o, req.headers()));
    let open = OPEN_PATHS.contains(&path.as_str());
    let mut resp = if let Some(o) = cross.filter(|o| !open && !allowed(&app, o)) {
        let e = ApiError::from(ServiceError::OriginNotAllowed {
            origin: o.to_owned(),
        });
        drain(&app, req).await;
        e.into_response()
    } else if cross.is_some() && is_preflight(&req) {
        preflight()
    } else if let Err(e) = check_key(&app, req.headers(), open) {
        drain(&app, req).await;
        ApiError::from(e).into_response()
    } else {
        req.extensions_mut().insert(RequestId(id.clone()));
        next.run(req).await
    };
    let headers = resp.headers_mut();
    if let Ok(v) = HeaderValue::from_str(&id) {
        headers.insert("x-request-id", v);
    }
    if let Some(o) = cross.filter(|o| allowed(&app, o)) {
        if let Ok(v) = HeaderValue::from_str(o) {
            headers.insert(header::ACCESS_CONTROL_ALLOW_ORIGIN, v);
            headers.insert(
                header::ACCESS_CONTROL_EXPOSE_HEADERS,
                HeaderValue::from_static(EXPOSED),
            );
        }
    }
    headers.insert(header::VARY, HeaderValue::from_static("origin"));
    if let Some(Refused(e)) = resp.extensions().get::<Refused>() {
        // Internal errors are logged as errors where they happen.
        if e.code != ErrorCode::Internal {
            app.refusals
                .refused(&path, &id, e.code.as_str(), &e.message);
        }
    }
    resp
}

/// Reads and drops the body of a refused request (up to `--max-body-bytes`, within
/// `--body-timeout-ms`), so that a client that sends everything before reading, like Python's
/// `http.client`, hears the refusal rather than a reset connection.
async fn drain(app: &AppState, req: Request) {
    use axum::body::HttpBody;
    use http_body_util::BodyExt;
    let limit = app.cfg.max_body_bytes;
    let mut body = req.into_body();
    if usize::try_from(body.size_hint().lower()).map_or(true, |n| n > limit) {
        return;
    }
    let read = async {
        let mut seen = 0usize;
        while let Some(Ok(frame)) = body.frame().await {
            seen = seen.saturating_add(frame.data_ref().map_or(0, |d| d.len()));
            if seen > limit {
                break;
            }
        }
    };
    let _ = tokio::time::timeout(app.cfg.body_timeout, read).await;
}

/// The client's `X-Request-Id` if it is at most 64 characters of `[A-Za-z0-9._-]`, else a new
/// one.
fn request_id(headers: &HeaderMap) -> String {
    let theirs = headers
        .get("x-request-id")
        .and_then(|v| v.to_str().ok())
        .filter(|v| {
            !v.is_empty()
                && v.len() <= 64
                && v.bytes()
                    .all(|b| b.is_ascii_alphanumeric() || b"._-".contains(&b))
        });
    match theirs {
        Some(id) => id.to_owned(),
        None => format!("tre-{:08x}", NEXT_ID.fetch_add(1, Ordering::Relaxed)),
    }
}

/// Whether `origin` is the server itself, as the client addressed it (`Host`).
fn same_origin(origin: &str, headers: &HeaderMap) -> bool {
    let Some(host) = headers.get(header::HOST).and_then(|h| h.to_str().ok()) else {
        return false;
    };
    origin
        .strip_prefix("http://")
        .or_else(|| origin.strip_prefix("https://"))
        .is_some_and(|rest| rest.eq_ignore_ascii_case(host))
}

/// Whether `origin` is on `--allow-origin` (`*` allows any).
fn allowed(app: &AppState, origin: &str) -> bool {
    app.cfg
        .allow_origins
        .iter()
        .any(|a| a == "*" || a.eq_ignore_ascii_case(origin))
}

fn is_preflight(req: &Request) -> bool {
    req.method() == Method::OPTIONS
        && req
            .headers()
            .contains_key(header::ACCESS_CONTROL_REQUEST_METHOD)
}

/// The answer to a CORS preflight of an allowed origin (its allow-origin is added by
/// [`guard`]).
fn preflight() -> Response {
    (
        StatusCode::NO_CONTENT,
        [
            (header::ACCESS_CONTROL_ALLOW_METHODS, "GET, POST"),
            (
                header::ACCESS_CONTROL_ALLOW_HEADERS,
                "authorization, content-type, x-request-id",
            ),
            (header::ACCESS_CONTROL_MAX_AGE, "600"),
        ],
    )
        .into_response()
}

/// With `--api-key`, the request must carry `Authorization: Bearer KEY` (open paths excepted).
fn check_key(app: &AppState, headers: &HeaderMap, open: bool) -> Result<(), RequestError> {
    let Some(key) = app.cfg.api_key.as_deref() else {
        return Ok(());
    };
    if open {
        return Ok(());
    }
    let given = headers
        .get(header::AUTHORIZATION)
        .and_then(|v| v.to_str().ok())
        .and_then(|v| {
            let (scheme, token) = v.trim().split_once(' ')?;
            scheme.eq_ignore_ascii_case("bearer").then(|| token.trim())
        });
    match given {
        None => Err(ServiceError::NoApiKey.into()),
        Some(token) if equal_in_constant_time(token.as_bytes(), key.as_bytes()) => Ok(()),
        Some(_) => Err(ServiceError::WrongApiKey.into()),
    }
}

/// Byte equality whose time depends on the lengths only, not on where the bytes differ.
fn equal_in_constant_time(a: &[u8], b: &[u8]) -> bool {
    a.len() == b.len() && a.iter().zip(b).fold(0u8, |acc, (x, y)| acc | (x ^ y)) == 0
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn request_ids_are_taken_only_when_plain() {
        let mut h = HeaderMap::new();
        h.insert("x-request-id", HeaderValue::from_static("robot-7.frame_12"));
        assert_eq!(request_id(&h), "robot-7.frame_12");
        h.insert("x-request-id", HeaderValue::from_static("a b"));
        assert!(request_id(&h).starts_with("tre-"));
        h.insert(
            "x-request-id",
            HeaderValue::from_str(&"a".repeat(65)).unwrap(),
        );
        assert!(request_id(&h).starts_with("tre-"));
    }

    #[test]
    fn same_origin_is_the_host_the_client_addressed() {
        let mut h = HeaderMap::new();
        h.insert(header::HOST, HeaderValue::from_static("127.0.0.1:8080"));
        assert!(same_origin("http://127.0.0.1:8080", &h));
        assert!(!same_origin("http://evil.example", &h));
        assert!(!same_origin("http://127.0.0.1:8080.evil.example", &h));
        assert!(equal_in_constant_time(b"key", b"key"));
        assert!(!equal_in_constant_time(b"key", b"kez"));
        assert!(!equal_in_constant_time(b"key", b"keys"));
    }
}
