//! Tests of decoding a frame under the limits.

use super::*;
use tre_proto::ErrorCode;

const LIMITS: DecodeLimits = DecodeLimits {
    max_pixels: 1_000_000,
    max_side: 4096,
    max_aspect: 8,
};

fn png_bytes(w: u32, h: u32) -> Vec<u8> {
    let mut out = Vec::new();
    io::encode_png(&DynamicImage::new_rgb8(w, h), &mut out).expect("encodes");
    out
}

#[test]
fn refuses_what_is_not_an_image() {
    let e = decode_image(ImagePart::Rgb, b"hello world", LIMITS).unwrap_err();
    assert_eq!(e.code(), ErrorCode::UnsupportedMedia);
    assert_eq!(
        decode_image(ImagePart::Rgb, b"", LIMITS)
            .unwrap_err()
            .code(),
        ErrorCode::BadImage
    );
}

#[test]
fn refuses_truncated_and_oversized_images() {
    let good = png_bytes(64, 48);
    assert_eq!(
        decode_image(ImagePart::Rgb, &good, LIMITS)
            .expect("decodes")
            .width(),
        64
    );
    let e = decode_image(ImagePart::Rgb, &good[..good.len() / 2], LIMITS).unwrap_err();
    assert_eq!(e.code(), ErrorCode::BadImage, "{e}");
    let small = DecodeLimits {
        max_pixels: 1000,
        ..LIMITS
    };
    assert_eq!(
        decode_image(ImagePart::Rgb, &good, small)
            .unwrap_err()
            .code(),
        ErrorCode::TooLarge
    );
}

#[test]
fn depth_must_be_16_bit() {
    let e = decode_depth(&png_bytes(4, 4), 1000.0, LIMITS).unwrap_err();
    assert_eq!(e.code(), ErrorCode::BadDepth);
}

fn npy_bytes<T: io::npy::NpyElement>(shape: &[usize], data: &[T]) -> Vec<u8> {
    let mut out = Vec::new();
    io::npy::write_npy(&mut out, shape, data).expect("writes");
    out
}

/// Every way depth can be wrong is a `bad_depth` error that says what depth may be, except
/// a size over the limit (`too_large`); float `.npy` depth is read as metres.
#[test]
fn depth_errors_are_depth_errors() {
    let grid = decode_depth(&npy_bytes(&[2, 3], &[1.5f32; 6]), 1000.0, LIMITS).unwrap();
    assert_eq!((grid.size(), grid[(2, 1)]), ((3, 2), 1.5));
    for (bytes, says) in [
        (Vec::new(), "16-bit grey PNG or a float .npy"),
        (b"hello world".to_vec(), "16-bit grey PNG or a float .npy"),
        (
            png_bytes(64, 48)[..100].to_vec(),
            "16-bit grey PNG or a float .npy",
        ),
        (
            npy_bytes(&[2, 3], &[1500u16; 6]),
            "for integer depth send a 16-bit PNG",
        ),
        (npy_bytes(&[0, 3], &[0.0f32; 0]), "it has no pixels"),
        (npy_bytes(&[2, 3, 1], &[1.0f32; 6]), "expected a 2-D array"),
        (npy_bytes(&[2, 3], &[0.0f32; 6]), "no valid pixel"),
        (npy_bytes(&[2, 3], &[1500.0f32; 6]), "in millimetres"),
    ] {
        let e = decode_depth(&bytes, 1000.0, LIMITS).unwrap_err();
        assert_eq!(e.code(), ErrorCode::BadDepth, "{e}");
        assert!(
            e.to_string().starts_with("depth: ") && e.to_string().contains(says),
            "{e}"
        );
    }
    let big = npy_bytes(&[1001, 1000], &vec![1.0f32; 1_001_000]);
    let e = decode_depth(&big, 1000.0, LIMITS).unwrap_err();
    assert_eq!(e.code(), ErrorCode::TooLarge, "{e}");
}

/// In the geometric mode an RGB part is not decoded (nothing uses it), but its header is
/// still checked: not an image, over the limit, or another size than the depth is an error.
#[test]
fn the_geometric_mode_checks_an_rgb_part_without_decoding_it() {
    let depth = npy_bytes(&[48, 64], &vec![1.5f32; 64 * 48]);
    let request = |rgb: Vec<u8>, mode| FrameRequest {
        rgb: Some(rgb),
        depth: Some(depth.clone()),
        camera: None,
        map: None,
        options: FrameOptions {
            mode,
            ..FrameOptions::default()
        },
    };
    let geometric = Some(Mode::Geometric);
    let frame = decode_frame(&request(png_bytes(64, 48), geometric), LIMITS).unwrap();
    assert!(frame.rgb.is_none() && frame.depth_m.is_some());
    // rgbd (the default with both parts) decodes it.
    let frame = decode_frame(&request(png_bytes(64, 48), None), LIMITS).unwrap();
    assert_eq!(frame.rgb.map(|i| i.dimensions()), Some((64, 48)));
    for (rgb, code) in [
        (png_bytes(32, 48), ErrorCode::BadDepth),
        (b"hello world".to_vec(), ErrorCode::UnsupportedMedia),
        (png_bytes(2000, 1000), ErrorCode::TooLarge),
    ] {
        let e = decode_frame(&request(rgb, geometric), LIMITS).unwrap_err();
        assert_eq!(e.code(), code, "{e}");
    }
}

/// `mode=rgb` predicts its own depth: a depth part sent with it is refused (422 `bad_input`,
/// naming rgbd and geometric), not dropped; without a mode the same parts run rgbd.
#[test]
fn depth_sent_with_the_rgb_mode_is_refused_not_dropped() {
    let request = |depth: Option<Vec<u8>>, mode| FrameRequest {
        rgb: Some(png_bytes(64, 48)),
        depth,
        camera: None,
        map: None,
        options: FrameOptions {
            mode,
            ..FrameOptions::default()
        },
    };
    let depth = npy_bytes(&[48, 64], &vec![1.5f32; 64 * 48]);
    let e = decode_frame(&request(Some(depth.clone()), Some(Mode::Rgb)), LIMITS).unwrap_err();
    assert_eq!(e.code(), ErrorCode::BadInput, "{e}");
    let says = e.to_string();
    assert!(
        says.contains("rgbd") && says.contains("geometric"),
        "{says}"
    );
    assert!(decode_frame(&request(None, Some(Mode::Rgb)), LIMITS).is_ok());
    let frame = decode_frame(&request(Some(depth), None), LIMITS).unwrap();
    assert!(frame.depth_m.is_some());
}

/// A file that declares a long thin image is refused from its header, naming the limit:
/// the side first (413), then the pixels (413), then the aspect ratio (422); depth alike.
#[test]
fn shapes_beyond_the_side_or_aspect_limits_are_refused_from_the_header() {
    let limits = DecodeLimits {
        max_pixels: 1 << 20,
        max_side: 2048,
        max_aspect: 8,
    };
    for (w, h, code, says) in [
        (4096, 1, ErrorCode::TooLarge, "--max-side"),
        (1, 4096, ErrorCode::TooLarge, "--max-side"),
        (2048, 1024, ErrorCode::TooLarge, "--max-pixels"),
        (2048, 255, ErrorCode::BadImage, "--max-aspect"),
        (2048, 1, ErrorCode::BadImage, "--max-aspect"),
    ] {
        let e = decode_image(ImagePart::Rgb, &png_bytes(w, h), limits).unwrap_err();
        assert_eq!(e.code(), code, "{w}×{h}: {e}");
        assert!(e.to_string().contains(says), "{w}×{h}: {e}");
    }
    assert!(decode_image(ImagePart::Rgb, &png_bytes(2048, 256), limits).is_ok());
    let e = decode_depth(&npy_bytes(&[1, 100], &[1.0f32; 100]), 1000.0, limits).unwrap_err();
    assert_eq!(e.code(), ErrorCode::BadDepth, "{e}");
    assert!(e.to_string().contains("--max-aspect"), "{e}");
}
