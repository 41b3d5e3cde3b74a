//! Every kind of bad input is a clear JSON error after which the server still serves; long
//! thin images and implausible cameras are refused at once.

use super::*;

/// A float32 `.npy` of one value whose header claims 2⁶² + 1 rows.
fn overflowing_npy() -> Vec<u8> {
    let header = "{'descr': '<f4', 'fortran_order': False, 'shape': (4611686018427387905, 1), }";
    let header = format!("{header:<117}\n");
    let mut npy = b"\x93NUMPY\x01\x00".to_vec();
    npy.extend((header.len() as u16).to_le_bytes());
    npy.extend(header.as_bytes());
    npy.extend(1.0f32.to_le_bytes());
    npy
}

#[test]
fn bad_input_is_a_clear_error_and_the_server_keeps_serving() {
    crate::common::skip_unless_shared!("data/real-rgbd");
    let mut server = Server::start(&[
        "--workers",
        "1",
        "--max-body-bytes",
        "3000000",
        "--max-pixels",
        "20000000",
    ]);
    let url = format!("{}/v1/roughness", server.url());
    rt().block_on(async {
        let cases = unreadable_bodies().into_iter().chain(oversize_bodies());
        for (what, ct, body, status, code) in cases {
            let (s, c, message) = error_of(post(&url, ct, body).await).await;
            assert_eq!((s, c.as_str()), (status, code), "{what}: {message}");
            assert!(!message.is_empty());
            still_serves(&server).await;
        }
        let rgb = std::fs::read(real("slambook2_ch7/1.png")).unwrap();
        let forms = bad_depth_and_part_forms(&rgb)
            .into_iter()
            .chain(bad_camera_forms(&rgb));
        for (what, form, code) in forms {
            let resp = post_form(&url, form).await;
            let (s, c, message) = error_of(resp).await;
            assert_eq!(c, code, "{what}: {message}");
            assert!(
                s == 400 || s == 422 || (s == 413 && c == "too_large"),
                "{what}: status {s}"
            );
            still_serves(&server).await;
        }
        bad_queries_are_refused(&url, &rgb).await;
    });
    clients_vanish_mid_request(server.addr);
    assert!(server.alive());
    rt().block_on(still_serves(&server));
    assert_eq!(get(server.addr, "/healthz").0, 200);
    let metrics = String::from_utf8(get(server.addr, "/metrics").1).unwrap();
    assert!(
        metrics.contains("tre_requests_total{endpoint=\"roughness\",outcome=\"bad_image\"} 4"),
        "{metrics}"
    );
    // Two oversize bodies and the depth .npy whose shape is beyond --max-pixels.
    assert!(
        metrics.contains("tre_requests_total{endpoint=\"roughness\",outcome=\"too_large\"} 3"),
        "{metrics}"
    );
}

/// A bad body: what it is, its content type, the body, and the status and error code it gets.
type BadBody = (&'static str, &'static str, Vec<u8>, u16, &'static str);

/// Bodies that are no image, or not a whole one.
fn unreadable_bodies() -> Vec<BadBody> {
    vec![
        (
            "not an image",
            "image/png",
            b"this is not a picture".to_vec(),
            415,
            "unsupported_media",
        ),
        (
            "wrong content type",
            "text/plain",
            b"hello".to_vec(),
            415,
            "unsupported_media",
        ),
        ("empty body", "image/png", Vec::new(), 422, "bad_image"),
        (
            "truncated PNG",
            "image/png",
            truncated("slambook2_ch7/1.png", 3),
            422,
            "bad_image",
        ),
        (
            // Decoded leniently, this was a frame half filled with grey.
            "truncated JPEG",
            "image/jpeg",
            truncated("metric3d_nyu/rgb/rgb_00000.jpg", 2),
            422,
            "bad_image",
        ),
    ]
}

/// The first `1/part` of the bytes of real file `path`.
fn truncated(path: &str, part: usize) -> Vec<u8> {
    let f = std::fs::read(real(path)).unwrap();
    f[..f.len() / part].to_vec()
}

/// Images of no size or too large a one, and a body over `--max-body-bytes`.
fn oversize_bodies() -> Vec<BadBody> {
    vec![
        (
            "zero-size image",
            "image/png",
            png_with_header(0, 0),
            422,
            "bad_image",
        ),
        (
            "decompression bomb",
            "image/png",
            png_with_header(100_000, 100_000),
            413,
            "too_large",
        ),
        (
            "oversize body",
            "image/png",
            vec![0u8; 3_500_000],
            413,
            "too_large",
        ),
    ]
}

/// A form of the frame `rgb` and a camera part.
fn with_camera(rgb: &[u8], json: &str) -> Form {
    Form::new()
        .part("rgb", Part::bytes(rgb.to_vec()))
        .part("camera", Part::text(json.to_owned()))
}

/// A form of the frame `rgb` and a depth part.
fn with_depth(rgb: &[u8], depth: Vec<u8>) -> Form {
    Form::new()
        .part("rgb", Part::bytes(rgb.to_vec()))
        .part("depth", Part::bytes(depth))
}

/// Bad depth parts and bad parts: what each is, the form, and its error code.
fn bad_depth_and_part_forms(rgb: &[u8]) -> Vec<(&'static str, Form, &'static str)> {
    let small_depth = {
        let mut out = Vec::new();
        image::DynamicImage::ImageLuma16(image::ImageBuffer::from_pixel(
            320,
            240,
            image::Luma([1000u16]),
        ))
        .write_to(&mut std::io::Cursor::new(&mut out), image::ImageFormat::Png)
        .unwrap();
        out
    };
    vec![
        (
            "depth of the wrong size",
            with_depth(rgb, small_depth),
            "bad_depth",
        ),
        (
            "unknown part",
            Form::new().part("picture", Part::bytes(rgb.to_vec())),
            "bad_request",
        ),
        (
            "the same part twice",
            Form::new()
                .part("rgb", Part::bytes(b"garbage".to_vec()))
                .part("rgb", Part::bytes(rgb.to_vec())),
            "bad_request",
        ),
        (
            // Its shape times the value size wraps around to a few bytes: this once
            // passed the length check and stopped the only worker. Its shape is now
            // beyond --max-pixels from the header, as a PNG's would be.
            "depth .npy whose shape overflows",
            with_depth(rgb, overflowing_npy()),
            "too_large",
        ),
        (
            "depth that is not an image",
            with_depth(rgb, b"not a depth map".to_vec()),
            "bad_depth",
        ),
        ("empty depth", with_depth(rgb, Vec::new()), "bad_depth"),
    ]
}

/// Bad camera parts: what each is, the form, and its error code.
fn bad_camera_forms(rgb: &[u8]) -> Vec<(&'static str, Form, &'static str)> {
    vec![
        (
            "camera that is not JSON",
            with_camera(rgb, "fx=500"),
            "bad_camera",
        ),
        (
            "nonsense intrinsics",
            with_camera(rgb, r#"{"fx": -5, "fy": 0, "cx": 1e300, "cy": 2}"#),
            "bad_camera",
        ),
        (
            // Ignored, it would leave the default 60° in place of the 30° meant.
            "the pitch under another name",
            with_camera(
                rgb,
                r#"{"fx": 500, "fy": 500, "cx": 320, "cy": 240, "pitch": 30}"#,
            ),
            "bad_camera",
        ),
        (
            "nonsense mounting",
            with_camera(
                rgb,
                r#"{"fx": 500, "fy": 500, "cx": 320, "cy": 240, "height_m": -3}"#,
            ),
            "bad_camera",
        ),
        (
            "a camera of another size than the frame",
            with_camera(
                rgb,
                r#"{"fx": 500, "fy": 500, "cx": 160, "cy": 120, "width": 320, "height": 240}"#,
            ),
            "bad_camera",
        ),
        (
            // Finite, but a typing error: the points would lie kilometres to the side.
            "a principal point far outside the image",
            with_camera(rgb, r#"{"fx": 500, "fy": 500, "cx": -1e9, "cy": 240}"#),
            "bad_camera",
        ),
        (
            // Valid as given, but 0 once scaled from 640×480 to the working size.
            "focal length that vanishes at the working size",
            with_camera(rgb, r#"{"fx": 5e-324, "fy": 5e-324, "cx": 320, "cy": 240}"#),
            "bad_camera",
        ),
    ]
}

/// Bad query parameters: an unknown format or normals method, thresholds out of range, a camera
/// given twice, and RGB-D mode without depth.
async fn bad_queries_are_refused(url: &str, rgb: &[u8]) {
    let rgb = rgb.to_vec();
    let (s, c, _) =
        error_of(post(&format!("{url}?format=jpeg2000"), "image/png", rgb.clone()).await).await;
    assert_eq!((s, c.as_str()), (400, "bad_request"));
    let (s, c, _) =
        error_of(post(&format!("{url}?normals=magic"), "image/png", rgb.clone()).await).await;
    assert_eq!((s, c.as_str()), (400, "bad_request"));
    for thresholds in [
        "max_slope_deg=95",
        "max_roughness_cm=0",
        "max_roughness_cm=-2",
    ] {
        let url = format!("{url}?outputs=traversable&{thresholds}");
        let (s, c, message) = error_of(post(&url, "image/png", rgb.clone()).await).await;
        assert_eq!((s, c.as_str()), (400, "bad_request"), "{thresholds}");
        let field = thresholds.split('=').next().unwrap();
        assert!(message.contains(field), "{message}");
    }
    let twice = Form::new().part("rgb", Part::bytes(rgb.clone())).part(
        "camera",
        Part::text(r#"{"fx": 500, "fy": 500, "cx": 320, "cy": 240}"#),
    );
    let resp = post_form(&format!("{url}?fx=525&fy=525&cx=319.5&cy=239.5"), twice).await;
    let (s, c, message) = error_of(resp).await;
    assert_eq!((s, c.as_str()), (400, "bad_request"), "{message}");
    let (s, c, _) = error_of(post(&format!("{url}?mode=rgbd"), "image/png", rgb).await).await;
    assert_eq!((s, c.as_str()), (422, "bad_input"));
}

/// Clients that vanish mid-request: three whose headers promise 2 MB of which part arrives, and
/// one that vanishes while its frame is being processed.
fn clients_vanish_mid_request(addr: std::net::SocketAddr) {
    // A client that vanishes mid-request: headers promise 2 MB, half arrives, then it is gone.
    for _ in 0..3 {
        let mut s = TcpStream::connect(addr).unwrap();
        let head = "POST /v1/roughness HTTP/1.1\r\nHost: x\r\nContent-Type: image/png\r\nContent-Length: 2000000\r\n\r\n";
        s.write_all(head.as_bytes()).unwrap();
        s.write_all(&std::fs::read(real("slambook2_ch7/1.png")).unwrap()[..50_000])
            .unwrap();
        drop(s);
    }
    // One that vanishes while its frame is being processed.
    let mut s = TcpStream::connect(addr).unwrap();
    let frame = std::fs::read(real("slambook2_ch7/1.png")).unwrap();
    let head = format!("POST /v1/roughness HTTP/1.1\r\nHost: x\r\nContent-Type: image/png\r\nContent-Length: {}\r\n\r\n", frame.len());
    s.write_all(head.as_bytes()).unwrap();
    s.write_all(&frame).unwrap();
    drop(s);
}

/// Long thin images are refused from their header at once, naming the limit: the 49 KB kind
/// of PNG that declares 16777216×1 (once 11 s of resizing) gets 413 `--max-side`, a 8192×2
/// one 422 `--max-aspect`; a camera part with a misspelt key or a height of 1e300 m is 422,
/// one with notes (`licence`) is read as `tre infer` reads it.
#[test]
fn long_thin_images_and_implausible_cameras_are_refused_at_once() {
    crate::common::skip_unless_shared!("data/real-rgbd");
    let server = Server::start(&["--workers", "1"]);
    let url = format!("{}/v1/roughness?mode=rgb", server.url());
    rt().block_on(async {
        for (w, h, status, says) in [
            (1 << 24, 1, 413, "--max-side"),
            (8192, 2, 422, "--max-aspect"),
        ] {
            let resp = post(&url, "image/png", png_with_header(w, h)).await;
            let (got, _, message) = error_of(resp).await;
            assert_eq!(got, status, "{w}×{h}: {message}");
            assert!(message.contains(says), "{w}×{h}: {message}");
        }
        let frame = std::fs::read(real("slambook2_ch7/1.png")).unwrap();
        let camera = r#"{"fx": 520.9, "fy": 521.0, "cx": 325.1, "cy": 249.7"#;
        for (extra, says) in [
            (r#", "depth_sacle": 5000}"#, "did you mean \"depth_scale\""),
            (r#", "licence": "MIT", "notes": "metadata"}"#, ""),
            (r#", "height_m": 1e300}"#, "height_m"),
            (r#", "pitch_deg": 135}"#, "pitch_deg"),
            (r#", "sensor": "a free-text description"}"#, ""),
            (
                r#", "distortion": [0.1, -0.2, 0, 0, 0]}"#,
                "lens distortion",
            ),
            (
                r#", "D": [0, 0, 0, 0, 0], "distortion_model": "plumb_bob"}"#,
                "",
            ),
        ] {
            let form = Form::new()
                .part("rgb", Part::bytes(frame.clone()).file_name("1.png"))
                .part("camera", Part::text(format!("{camera}{extra}")));
            let resp = post_form(&url, form).await;
            if says.is_empty() {
                assert_eq!(resp.status().as_u16(), 200, "{extra}");
                continue;
            }
            let (status, code, message) = error_of(resp).await;
            assert_eq!((status, code.as_str()), (422, "bad_camera"), "{message}");
            assert!(message.contains(says), "{message}");
        }
        let resp = post(
            &format!("{url}&height_m=0&fx=500&fy=500&cx=320&cy=240"),
            "image/png",
            frame,
        )
        .await;
        assert_eq!(error_of(resp).await.0, 422);
        // A long query is not echoed in full.
        let long = format!("{url}&{}=1", "q".repeat(20_000));
        let (status, _, message) = error_of(post(&long, "image/png", Vec::new()).await).await;
        assert_eq!(status, 400);
        assert!(
            message.chars().count() <= 401,
            "{} characters",
            message.len()
        );
    });
}
