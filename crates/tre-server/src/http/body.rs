//! Reading an HTTP request's body within its limits (size, pace) and parsing it as a frame: a
//! bare image or multipart `rgb`, `depth`, `camera`; the images' shapes checked from their
//! headers before the frame is queued.

use axum::body::{Body, Bytes, HttpBody};
use axum::extract::{FromRequest, Multipart, Request};
use axum::http::header;
use http_body_util::BodyExt;

use crate::error::{BodyError, ImagePart, LimitError, RequestError};
use crate::request::{image_header, strict_camera, DecodeLimits, FrameRequest};
use crate::{AppState, OVERSIZE_READ_FACTOR};

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
            Err(e) if e.is_over_limit() => return Err(e.into()),
            // Other depth errors are answered by the worker, saying what depth may be.
            _ => {}
        }
    }
    Ok(())
}

/// Reads the body within the byte limit: a bare image, or multipart with `rgb`, `depth`,
/// `camera`.
pub(super) async fn read_body(app: &AppState, req: Request) -> Result<FrameRequest, RequestError> {
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
            .map_err(BodyError::MultipartHeader)?;
        let multipart = Multipart::from_request(req, &())
            .await
            .map_err(BodyError::MultipartBoundary)?;
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
        return Err(BodyError::ContentType {
            essence: essence.to_owned(),
        }
        .into());
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
    let too_large = || LimitError::BodyTooLarge { limit };
    // The declared length, if any, sizes the buffer once (never beyond the limit).
    let declared = usize::try_from(body.size_hint().lower()).unwrap_or(usize::MAX);
    if declared > most {
        return Err(too_large().into());
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
        let frame = frame.map_err(BodyError::ReadBody)?;
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
        return Err(too_large().into());
    }
    Ok(Bytes::from(kept))
}

/// Window over which a body's rate is averaged (`--min-body-rate`); the first one is the grace
/// a client has before its rate counts. One window for HTTP bodies and stream messages.
pub(crate) use crate::pace::PACE_WINDOW as BODY_RATE_WINDOW;

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
            return Err(LimitError::BodyTooSlow {
                rate,
                secs,
                min_bytes_per_s: self.min_bytes_per_s,
            }
            .into());
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
    while let Some(field) = m.next_field().await.map_err(BodyError::Multipart)? {
        let name = field.name().unwrap_or("").to_owned();
        let data = match field.bytes().await {
            Ok(data) => data,
            Err(source) => return Err(BodyError::MultipartField { name, source }.into()),
        };
        match name.as_str() {
            "rgb" => set_once(&mut frame.rgb, &name, || Ok(data.to_vec()))?,
            "depth" => set_once(&mut frame.depth, &name, || Ok(data.to_vec()))?,
            "camera" => set_once(&mut frame.camera, &name, || strict_camera(&data, limits))?,
            _ => return Err(BodyError::UnknownPart { name }.into()),
        }
    }
    if frame.rgb.is_none() && frame.depth.is_none() {
        return Err(BodyError::NoImagePart.into());
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
        return Err(BodyError::PartTwice {
            name: name.to_owned(),
        }
        .into());
    }
    *slot = Some(value()?);
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::time::Duration;
    use tre_proto::ErrorCode;

    /// Within a window nothing is judged; at its end, too few bytes is a 408 naming the option,
    /// enough starts the next window afresh (earlier bytes do not carry over).
    #[test]
    fn body_pace_judges_each_window() {
        let mut pace = BodyPace::new(1024);
        let t0 = pace.since;
        assert_eq!(pace.deadline(), Some(t0 + BODY_RATE_WINDOW));
        pace.check(10, t0 + Duration::from_secs(1)).unwrap();
        pace.check(6000, t0 + BODY_RATE_WINDOW).unwrap();
        assert_eq!((pace.since, pace.bytes), (t0 + BODY_RATE_WINDOW, 0));
        let e = pace.check(100, t0 + 2 * BODY_RATE_WINDOW).unwrap_err();
        assert_eq!(e.code(), ErrorCode::RequestTimeout);
        assert!(e.to_string().contains("--min-body-rate"), "{e}");
        assert!(e.to_string().contains("20 bytes/s"), "{e}");
        let mut off = BodyPace::new(0);
        assert_eq!(off.deadline(), None);
        off.check(0, t0 + Duration::from_secs(3600)).unwrap();
    }
}
