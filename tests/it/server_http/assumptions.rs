//! No silent guesses over HTTP: every answer names its mode and its gravity, says what stood in
//! for what the request did not give, and depth sent as the RGB frame is refused; depth sent with
//! `mode=rgb` is refused, and a three-state map at least 90% unknown says so.

use super::*;

/// The value of header `name`, or "".
fn header(h: &reqwest::header::HeaderMap, name: &str) -> String {
    h.get(name)
        .map(|v| v.to_str().unwrap().to_owned())
        .unwrap_or_default()
}

/// The three-state map part's bytes of a multipart answer, PNG-decoded.
async fn traversal_values(resp: reqwest::Response) -> Vec<u8> {
    let ct = header(resp.headers(), "content-type");
    let body = resp.bytes().await.unwrap();
    let boundary = format!("--{}", ct.split("boundary=").nth(1).unwrap());
    let text = body.as_ref();
    let start = text
        .windows(b"name=\"traversal\"".len())
        .position(|w| w == b"name=\"traversal\"")
        .unwrap();
    let data = start
        + text[start..]
            .windows(4)
            .position(|w| w == b"\r\n\r\n")
            .unwrap()
        + 4;
    let end = data
        + text[data..]
            .windows(boundary.len())
            .position(|w| w == boundary.as_bytes())
            .unwrap()
        - 2;
    image::load_from_memory(&text[data..end])
        .unwrap()
        .to_luma8()
        .into_raw()
}

/// A form of `rgb` with optional `depth` and `camera` parts.
fn form(rgb: &[u8], depth: Option<&[u8]>, camera: Option<&str>) -> Form {
    let mut f = Form::new().part("rgb", Part::bytes(rgb.to_vec()));
    if let Some(d) = depth {
        f = f.part("depth", Part::bytes(d.to_vec()));
    }
    if let Some(c) = camera {
        f = f.part("camera", Part::text(c.to_owned()));
    }
    f
}

#[test]
fn answers_name_their_mode_gravity_and_assumptions() {
    crate::common::skip_unless_shared!("data/real-rgbd");
    let server = Server::start(&["--workers", "1"]);
    let url = format!("{}/v1/roughness", server.url());
    let rgb = std::fs::read(real("slambook2_ch7/1.png")).unwrap();
    let depth = std::fs::read(real("slambook2_ch7/1_depth.png")).unwrap();
    // The shared camera file, with its notes (depth_file_format, licence): the README example.
    let shared_camera = std::fs::read_to_string(real("slambook2_ch7/intrinsics.json")).unwrap();
    rt().block_on(async {
        // Depth sent as the RGB frame: refused, saying where depth goes.
        let (s, code, message) = error_of(post(&url, "image/png", depth.clone()).await).await;
        assert_eq!((s, code.as_str()), (422, "bad_image"), "{message}");
        assert!(message.contains("16-bit grey") && message.contains("depth"), "{message}");

        // RGB + depth without a camera: runs, and says it assumed intrinsics, the depth scale
        // and the mode, in the keys header and in words.
        let resp = post_form(&url, form(&rgb, Some(&depth), None)).await;
        assert_eq!(resp.status().as_u16(), 200);
        let h = resp.headers();
        assert_eq!(header(h, "x-tre-mode"), "rgbd");
        assert_eq!(header(h, "x-tre-assumed"), "intrinsics, depth_scale, mode");
        let warnings: Vec<&str> = h.get_all("warning").iter().map(|v| v.to_str().unwrap()).collect();
        // The three assumptions, and what the millimetres made of this TUM frame (5000 units
        // per metre): the ground 7.4 m below the camera, with the scale that fits named.
        assert_eq!(warnings.len(), 4, "{warnings:?}");
        let implausible = warnings[3].contains("below the camera") && warnings[3].contains("5000");
        assert!(implausible && warnings[1].contains("read as millimetres"), "{warnings:?}");

        geometric_names_its_sensor_or_assumes_one(&url, (&rgb, &depth), &shared_camera).await;

        // rgb without a mounting: the prior's mounting is assumed and gravity is unknown, so the
        // three-state map has no traversable pixel.
        let camera = r#"{"fx": 520.9, "fy": 521.0, "cx": 325.1, "cy": 249.7, "sensor": "kinect_v1"}"#;
        let resp = post_form(
            &format!("{url}?mode=rgb&outputs=traversal"),
            form(&rgb, None, Some(camera)),
        )
        .await;
        assert_eq!(resp.status().as_u16(), 200);
        let h = resp.headers();
        assert_eq!(header(h, "x-tre-assumed"), "mounting");
        assert!(header(h, "x-tre-gravity").starts_with("unknown; reason="));
        let t = traversal_values(resp).await;
        assert!(!t.is_empty() && t.iter().all(|&v| v != 1), "traversable without gravity");

        // The same with a stated mounting: gravity is stated, and some pixels are traversable.
        let camera = r#"{"fx": 520.9, "fy": 521.0, "cx": 325.1, "cy": 249.7, "pitch_deg": 30, "height_m": 1.2}"#;
        let resp = post_form(&format!("{url}?mode=rgb"), form(&rgb, None, Some(camera))).await;
        let h = resp.headers();
        assert_eq!(header(h, "x-tre-assumed"), "");
        assert_eq!(
            header(h, "x-tre-gravity"),
            "stated; pitch_deg=30.0; roll_deg=0.0; height_m=1.20"
        );
        // A height without a pitch would leave a guessed pitch in charge: refused.
        let form = Form::new()
            .part("rgb", Part::bytes(rgb.clone()))
            .part("camera", Part::text(r#"{"fx": 520.9, "fy": 521.0, "cx": 325.1, "cy": 249.7, "height_m": 1.2}"#));
        let (s, code, message) = error_of(post_form(&url, form).await).await;
        assert_eq!((s, code.as_str()), (422, "bad_camera"), "{message}");
        assert!(message.contains("pitch_deg"), "{message}");
    });
}

/// Nothing dropped or passed off over HTTP: depth sent with `mode=rgb` is refused naming the
/// modes that use it, and a three-state map at least 90% unknown says so in a `Warning`.
#[test]
fn depth_with_rgb_is_refused_and_a_mostly_unknown_map_says_so() {
    let sample = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("samples/tum_fr2_desk");
    let rgb = std::fs::read(sample.join("rgb.png")).unwrap();
    let depth = std::fs::read(sample.join("depth.png")).unwrap();
    let camera = std::fs::read_to_string(sample.join("camera.json")).unwrap();
    let server = Server::start(&["--workers", "1"]);
    let url = format!("{}/v1/roughness", server.url());
    rt().block_on(async {
        let both = form(&rgb, Some(&depth), Some(&camera));
        let (s, code, message) = error_of(post_form(&format!("{url}?mode=rgb"), both).await).await;
        assert_eq!((s, code.as_str()), (422, "bad_input"), "{message}");
        assert!(
            message.contains("rgbd") && message.contains("geometric"),
            "{message}"
        );
        let mut seen = Vec::new();
        for (mode, depth) in [("rgb", None), ("rgbd", Some(depth.as_slice()))] {
            let parts = form(&rgb, depth, Some(&camera));
            let query = format!("{url}?mode={mode}&outputs=traversal");
            let resp = post_form(&query, parts).await;
            assert_eq!(resp.status().as_u16(), 200, "{mode}");
            let warnings: Vec<String> = resp
                .headers()
                .get_all("warning")
                .iter()
                .map(|v| v.to_str().unwrap().to_owned())
                .collect();
            let t = traversal_values(resp).await;
            let unknown = t.iter().filter(|&&v| v == 0).count() as f64 / t.len() as f64;
            let said = warnings.iter().any(|w| w.contains("three-state map is"));
            let mostly = unknown >= tre::pipeline::MOSTLY_UNKNOWN_SHARE;
            assert_eq!(said, mostly, "{mode}: {unknown} unknown, {warnings:?}");
            seen.push(mostly);
        }
        // The rgb mode's calibrated intervals leave this frame unknown; the sensor's depth does not.
        assert_eq!(seen, [true, false]);
    });
}

/// The shared camera file in the geometric mode: its "sensor" is a description that names no
/// noise model, so the depth is read as exact, and the answer says so; named by the request,
/// nothing is assumed.
async fn geometric_names_its_sensor_or_assumes_one(
    url: &str,
    (rgb, depth): (&[u8], &[u8]),
    shared_camera: &str,
) {
    // Three-state; no mounting stated, so gravity comes from the depth's ground plane.
    let shared = form(rgb, Some(depth), Some(shared_camera));
    let resp = post_form(&format!("{url}?mode=geometric&outputs=traversable"), shared).await;
    assert_eq!(resp.status().as_u16(), 200);
    let h = resp.headers();
    assert_eq!(header(h, "x-tre-mode"), "geometric");
    assert_eq!(header(h, "x-tre-assumed"), "sensor");
    let warnings: Vec<&str> = h
        .get_all("warning")
        .iter()
        .map(|v| v.to_str().unwrap())
        .collect();
    assert!(
        warnings.iter().any(|w| w.contains("read as exact")),
        "{warnings:?}"
    );
    assert!(
        header(h, "x-tre-gravity").starts_with("estimated; pitch_deg="),
        "{}",
        header(h, "x-tre-gravity")
    );
    // Named by the request, nothing is assumed.
    let named = form(rgb, Some(depth), Some(shared_camera));
    let resp = post_form(&format!("{url}?mode=geometric&sensor=kinect_v1"), named).await;
    assert_eq!(resp.status().as_u16(), 200);
    assert_eq!(header(resp.headers(), "x-tre-assumed"), "");
}
