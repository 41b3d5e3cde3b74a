//! Entry points that run a client's bytes through every decoder it can reach, checking what must
//! hold whatever the bytes: no panic, an answer or a client error (never `internal`), and
//! nothing decoded beyond the limits. Each returns whether the bytes were accepted. The property tests below and the `cargo fuzz` targets in
//! `fuzz/` (docs/security.md) call the same functions.

use axum::body::Bytes;

use super::error::ApiError;
use super::http::{check_shapes, parse_body};
use super::proto::{decode_client, Incoming, StreamSettings};
use super::request::{
    decode_depth, decode_frame, decode_image, strict_camera, DecodeLimits, ImagePart,
};
use tre_io::npy;
use tre_pipeline::FrameInput;
use tre_proto::ErrorCode;

/// The content type the multipart entry point parses its bytes as.
pub const MULTIPART_TYPE: &str = "multipart/form-data; boundary=tre-fuzz-Boundary";

/// The limits every entry point decodes under: the service's defaults.
pub fn limits() -> DecodeLimits {
    DecodeLimits::default()
}

/// A refusal must be a client error with a message, whatever the bytes; `false`.
fn refused(what: &str, e: impl Into<ApiError>) -> bool {
    let e = e.into();
    assert!(
        e.code != ErrorCode::Internal && (400..500).contains(&e.code.http_status()),
        "{what}: bytes from a client gave {:?}: {}",
        e.code,
        e.message
    );
    assert!(!e.message.is_empty(), "{what}: an error without a message");
    false
}

/// A `w`×`h` result must be within the limits; `true`.
fn within(what: &str, (w, h): (usize, usize)) -> bool {
    let l = limits();
    assert!(
        w > 0 && h > 0 && w.max(h) <= l.max_side && w * h <= l.max_pixels,
        "{what}: decoded {w}×{h}, beyond the limits {l:?}"
    );
    true
}

/// An image part (PNG or JPEG): the header-shape check, then decoding.
pub fn image(data: &[u8]) -> bool {
    match decode_image(ImagePart::Rgb, data, limits()) {
        Ok(img) => within("image", (img.width() as usize, img.height() as usize)),
        Err(e) => refused("image", e),
    }
}

/// A depth part: a 16-bit grey PNG (or any image, refused) or a `.npy`.
pub fn depth(data: &[u8]) -> bool {
    match decode_depth(data, 1000.0, limits()) {
        Ok(d) => within("depth", d.size()),
        Err(e) => refused("depth", e),
    }
}

/// `.npy` parsing alone, bounded as a client's depth is.
pub fn npy(data: &[u8]) -> bool {
    let max = limits().max_pixels;
    let Ok(a) = npy::read_npy_within(data, max) else {
        return false;
    };
    assert_eq!(a.data.len(), a.shape.iter().product::<usize>());
    assert!(a.data.len() <= max, "npy: {} values read", a.data.len());
    true
}

/// A camera JSON part (or query camera) as the service reads it.
pub fn camera(data: &[u8]) -> bool {
    match strict_camera(data, limits()) {
        Ok(cam) => {
            assert!(
                cam.fx.is_finite() && cam.fy.is_finite(),
                "camera: accepted {cam:?}"
            );
            true
        }
        Err(e) => refused("camera", e),
    }
}

/// A frame's decoding by a worker, as after either transport.
fn frame(what: &str, req: &super::request::FrameRequest) -> bool {
    match decode_frame(req, limits()) {
        Ok(input) => frame_within(what, &input),
        Err(e) => refused(what, e),
    }
}

fn frame_within(what: &str, input: &FrameInput) -> bool {
    if let Some(rgb) = &input.rgb {
        within(what, (rgb.width() as usize, rgb.height() as usize));
    }
    if let Some(d) = &input.depth_m {
        within(what, d.size());
    }
    true
}

/// An HTTP body of [`MULTIPART_TYPE`]: the handler's multipart parsing and shape checks, then the
/// worker's decoding.
pub fn multipart(data: &[u8]) -> bool {
    let runtime = tokio::runtime::Builder::new_current_thread()
        .build()
        .expect("a current-thread runtime without drivers builds; this is a bug");
    let body = Bytes::copy_from_slice(data);
    let parsed = runtime.block_on(parse_body(MULTIPART_TYPE, body, limits()));
    let req = match parsed.and_then(|req| check_shapes(&req, limits()).map(|()| req)) {
        Ok(req) => req,
        Err(e) => return refused("multipart", e),
    };
    frame("multipart", &req)
}

/// A binary stream message: protobuf decoding and conversion, then a frame's decoding.
pub fn stream(data: &[u8]) -> bool {
    match decode_client(data) {
        Ok(Incoming::Hello(_)) => true,
        Ok(Incoming::Frame(f)) => frame("stream", &f.into_request(&StreamSettings::default())),
        Err((_, e)) => refused("stream", e),
    }
}

#[cfg(test)]
mod tests;
