//! `POST /v1/roughness` and the operational endpoints on a real `tre serve` over loopback:
//! answers equal `tre infer`, every kind of bad input is a clear JSON error after which the
//! server still serves, and overload is refused at once while accepted work finishes.
#![allow(clippy::unwrap_used)] // Test helpers fail loudly by design.

use crate::common;

use std::io::Write;
use std::net::TcpStream;

use common::{get, infer_png16, png16_values, png_with_header, real, Server};
use reqwest::multipart::{Form, Part};

fn rt() -> tokio::runtime::Runtime {
    tokio::runtime::Builder::new_multi_thread()
        .enable_all()
        .build()
        .unwrap()
}

async fn post(url: &str, content_type: &str, body: Vec<u8>) -> reqwest::Response {
    reqwest::Client::new()
        .post(url)
        .header("content-type", content_type)
        .body(body)
        .send()
        .await
        .unwrap()
}

/// Status, error code and message of a JSON error answer.
async fn error_of(resp: reqwest::Response) -> (u16, String, String) {
    let status = resp.status().as_u16();
    assert_eq!(resp.headers()["content-type"], "application/json");
    let v: serde_json::Value = serde_json::from_slice(&resp.bytes().await.unwrap()).unwrap();
    let e = &v["error"];
    (
        status,
        e["code"].as_str().unwrap().to_owned(),
        e["message"].as_str().unwrap().to_owned(),
    )
}

/// A small real frame must still be answered with a map (the server is still serving).
async fn still_serves(server: &Server) {
    let frame = std::fs::read(real("slambook2_ch7/1.png")).unwrap();
    let resp = post(
        &format!("{}/v1/roughness?mode=rgb", server.url()),
        "image/png",
        frame,
    )
    .await;
    assert_eq!(resp.status().as_u16(), 200, "the server stopped serving");
}

#[test]
fn answers_equal_tre_infer_in_rgb_and_rgbd() {
    let server = Server::start(&["--workers", "1"]);
    rt().block_on(async {
        let rgb_path = real("slambook2_ch7/1.png");
        let frame = std::fs::read(&rgb_path).unwrap();
        let resp = post(
            &format!("{}/v1/roughness", server.url()),
            "image/png",
            frame.clone(),
        )
        .await;
        assert_eq!(resp.status().as_u16(), 200);
        let h = resp.headers().clone();
        assert_eq!(h["x-roughness-scale-m"], "0.0001");
        assert_eq!(
            (
                h["x-image-width"].to_str().unwrap(),
                h["x-image-height"].to_str().unwrap()
            ),
            ("640", "480")
        );
        assert_eq!(h["x-working-size"], "256x192");
        let timing = h["server-timing"].to_str().unwrap().to_owned();
        for stage in ["depth;dur=", "normals;dur=", "refine;dur=", "centroid;dur="] {
            assert!(timing.contains(stage), "{timing}");
        }
        // The worker's whole job: decoding first, encoding (and any extra maps) last.
        let stages: Vec<&str> = timing
            .split(", ")
            .map(|s| s.split(';').next().unwrap())
            .collect();
        assert_eq!(
            (stages.first(), stages.last()),
            (Some(&"decode"), Some(&"encode")),
            "{timing}"
        );
        let served = png16_values(&resp.bytes().await.unwrap());
        let reference = infer_png16(&[rgb_path.to_str().unwrap(), "--mode", "rgb"]);
        assert_eq!(served, reference, "HTTP rgb answer differs from tre infer");
        let url = format!("{}/v1/roughness?normals=ls", server.url());
        let served = png16_values(
            &post(&url, "image/png", frame.clone())
                .await
                .bytes()
                .await
                .unwrap(),
        );
        let reference = infer_png16(&[
            rgb_path.to_str().unwrap(),
            "--mode",
            "rgb",
            "--normals",
            "ls",
        ]);
        assert_eq!(
            served, reference,
            "HTTP rgb answer with LS normals differs from tre infer"
        );

        let depth_path = real("slambook2_ch7/1_depth.png");
        let camera_path = real("slambook2_ch7/intrinsics.json");
        let form = Form::new()
            .part("rgb", Part::bytes(frame).file_name("1.png"))
            .part("depth", Part::bytes(std::fs::read(&depth_path).unwrap()))
            .part("camera", Part::text(camera_part(&camera_path)));
        let resp = reqwest::Client::new()
            .post(format!("{}/v1/roughness?seed=3", server.url()))
            .multipart(form)
            .send()
            .await
            .unwrap();
        assert_eq!(resp.status().as_u16(), 200);
        let served = png16_values(&resp.bytes().await.unwrap());
        let reference = infer_png16(&[
            rgb_path.to_str().unwrap(),
            "--depth",
            depth_path.to_str().unwrap(),
            "--camera",
            camera_path.to_str().unwrap(),
            "--seed",
            "3",
        ]);
        assert_eq!(served, reference, "HTTP rgbd answer differs from tre infer");
    });
}

#[test]
fn serve_dsac_hypotheses_sets_the_frames_default_and_is_checked() {
    let server = Server::start(&["--workers", "1", "--dsac-hypotheses", "4"]);
    let rgb_path = real("slambook2_ch7/1.png");
    let frame = std::fs::read(&rgb_path).unwrap();
    let served = rt().block_on(async {
        let resp = post(
            &format!("{}/v1/roughness", server.url()),
            "image/png",
            frame,
        )
        .await;
        assert_eq!(resp.status().as_u16(), 200);
        png16_values(&resp.bytes().await.unwrap())
    });
    let rgb = rgb_path.to_str().unwrap();
    let four = infer_png16(&[rgb, "--mode", "rgb", "--dsac-hypotheses", "4"]);
    assert_eq!(
        served, four,
        "HTTP answer with K = 4 differs from tre infer"
    );
    let twelve = infer_png16(&[rgb, "--mode", "rgb"]);
    assert_ne!(four, twelve, "K = 4 and K = 12 gave the same map");
    // A request chooses its own; a bad number is a clear error and the server goes on.
    let url = format!("{}/v1/roughness", server.url());
    rt().block_on(async {
        let frame = std::fs::read(&rgb_path).unwrap();
        let resp = post(
            &format!("{url}?dsac_hypotheses=12"),
            "image/png",
            frame.clone(),
        )
        .await;
        assert_eq!(resp.status().as_u16(), 200);
        assert_eq!(png16_values(&resp.bytes().await.unwrap()), twelve);
        for bad in ["0", "65", "many"] {
            let bad_url = format!("{url}?dsac_hypotheses={bad}");
            let (s, c, m) = error_of(post(&bad_url, "image/png", frame.clone()).await).await;
            assert_eq!((s, c.as_str()), (400, "bad_request"), "{bad}: {m}");
            assert!(m.contains("dsac_hypotheses"), "{bad}: {m}");
        }
        still_serves(&server).await;
    });

    for bad in ["0", "65"] {
        let out = std::process::Command::new(env!("CARGO_BIN_EXE_tre"))
            .args(["serve", "--addr", "127.0.0.1:0", "--dsac-hypotheses", bad])
            .output()
            .unwrap();
        assert!(
            !out.status.success(),
            "--dsac-hypotheses {bad} was accepted"
        );
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(
            err.contains("--dsac-hypotheses") && err.contains("1..=64"),
            "{err}"
        );
    }
}

#[test]
fn formats_and_extra_outputs() {
    let server = Server::start(&["--workers", "1"]);
    rt().block_on(async {
        let frame = common::pattern_png(96, 64);
        let url = format!("{}/v1/roughness?format=npy", server.url());
        let resp = post(&url, "image/png", frame.clone()).await;
        assert_eq!(resp.status().as_u16(), 200);
        let npy = resp.bytes().await.unwrap();
        assert!(npy.starts_with(b"\x93NUMPY"));
        let a = tre::io::npy::read_npy(std::io::Cursor::new(&npy[..])).unwrap();
        assert_eq!(a.shape, vec![64, 96]);

        let url = format!(
            "{}/v1/roughness?format=color&outputs=depth,traversable,slope,normals,boundary",
            server.url()
        );
        let resp = post(&url, "image/png", frame).await;
        assert_eq!(resp.status().as_u16(), 200);
        let ct = resp.headers()["content-type"].to_str().unwrap().to_owned();
        assert!(ct.starts_with("multipart/mixed; boundary="), "{ct}");
        let body = resp.bytes().await.unwrap();
        let text = String::from_utf8_lossy(&body);
        for name in [
            "roughness",
            "depth",
            "traversable",
            "slope",
            "normals",
            "boundary",
        ] {
            assert!(
                text.contains(&format!("name=\"{name}\"")),
                "part {name} missing"
            );
        }
    });
}

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
        let cases: Vec<(&str, &str, Vec<u8>, u16, &str)> = vec![
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
                {
                    let f = std::fs::read(real("slambook2_ch7/1.png")).unwrap();
                    f[..f.len() / 3].to_vec()
                },
                422,
                "bad_image",
            ),
            (
                // Decoded leniently, this was a frame half filled with grey.
                "truncated JPEG",
                "image/jpeg",
                {
                    let f = std::fs::read(real("metric3d_nyu/rgb/rgb_00000.jpg")).unwrap();
                    f[..f.len() / 2].to_vec()
                },
                422,
                "bad_image",
            ),
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
        ];
        for (what, ct, body, status, code) in cases {
            let (s, c, message) = error_of(post(&url, ct, body).await).await;
            assert_eq!((s, c.as_str()), (status, code), "{what}: {message}");
            assert!(!message.is_empty());
            still_serves(&server).await;
        }
        let rgb = std::fs::read(real("slambook2_ch7/1.png")).unwrap();
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
        let with_camera = |json: &str| {
            Form::new()
                .part("rgb", Part::bytes(rgb.clone()))
                .part("camera", Part::text(json.to_owned()))
        };
        let with_depth = |depth: Vec<u8>| {
            Form::new()
                .part("rgb", Part::bytes(rgb.clone()))
                .part("depth", Part::bytes(depth))
        };
        let forms: Vec<(&str, Form, &str)> = vec![
            (
                "depth of the wrong size",
                with_depth(small_depth),
                "bad_depth",
            ),
            (
                "camera that is not JSON",
                with_camera("fx=500"),
                "bad_camera",
            ),
            (
                "nonsense intrinsics",
                with_camera(r#"{"fx": -5, "fy": 0, "cx": 1e300, "cy": 2}"#),
                "bad_camera",
            ),
            (
                // Ignored, it would leave the default 60° in place of the 30° meant.
                "the pitch under another name",
                with_camera(r#"{"fx": 500, "fy": 500, "cx": 320, "cy": 240, "pitch": 30}"#),
                "bad_camera",
            ),
            (
                "nonsense mounting",
                with_camera(r#"{"fx": 500, "fy": 500, "cx": 320, "cy": 240, "height_m": -3}"#),
                "bad_camera",
            ),
            (
                "unknown part",
                Form::new().part("picture", Part::bytes(rgb.clone())),
                "bad_request",
            ),
            (
                "the same part twice",
                Form::new()
                    .part("rgb", Part::bytes(b"garbage".to_vec()))
                    .part("rgb", Part::bytes(rgb.clone())),
                "bad_request",
            ),
            (
                "a camera of another size than the frame",
                with_camera(
                    r#"{"fx": 500, "fy": 500, "cx": 160, "cy": 120, "width": 320, "height": 240}"#,
                ),
                "bad_camera",
            ),
            (
                // Finite, but a typing error: the points would lie kilometres to the side.
                "a principal point far outside the image",
                with_camera(r#"{"fx": 500, "fy": 500, "cx": -1e9, "cy": 240}"#),
                "bad_camera",
            ),
            (
                // Its shape times the value size wraps around to a few bytes: this once
                // passed the length check and stopped the only worker. Its shape is now
                // beyond --max-pixels from the header, as a PNG's would be.
                "depth .npy whose shape overflows",
                with_depth(overflowing_npy()),
                "too_large",
            ),
            (
                "depth that is not an image",
                with_depth(b"not a depth map".to_vec()),
                "bad_depth",
            ),
            ("empty depth", with_depth(Vec::new()), "bad_depth"),
            (
                // Valid as given, but 0 once scaled from 640×480 to the working size.
                "focal length that vanishes at the working size",
                with_camera(r#"{"fx": 5e-324, "fy": 5e-324, "cx": 320, "cy": 240}"#),
                "bad_camera",
            ),
        ];
        for (what, form, code) in forms {
            let resp = reqwest::Client::new()
                .post(&url)
                .multipart(form)
                .send()
                .await
                .unwrap();
            let (s, c, message) = error_of(resp).await;
            assert_eq!(c, code, "{what}: {message}");
            assert!(
                s == 400 || s == 422 || (s == 413 && c == "too_large"),
                "{what}: status {s}"
            );
            still_serves(&server).await;
        }
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
        let resp = reqwest::Client::new()
            .post(format!("{url}?fx=525&fy=525&cx=319.5&cy=239.5"))
            .multipart(twice)
            .send()
            .await
            .unwrap();
        let (s, c, message) = error_of(resp).await;
        assert_eq!((s, c.as_str()), (400, "bad_request"), "{message}");
        let (s, c, _) = error_of(post(&format!("{url}?mode=rgbd"), "image/png", rgb).await).await;
        assert_eq!((s, c.as_str()), (422, "bad_input"));
    });
    // A client that vanishes mid-request: headers promise 2 MB, half arrives, then it is gone.
    for _ in 0..3 {
        let mut s = TcpStream::connect(server.addr).unwrap();
        let head = "POST /v1/roughness HTTP/1.1\r\nHost: x\r\nContent-Type: image/png\r\nContent-Length: 2000000\r\n\r\n";
        s.write_all(head.as_bytes()).unwrap();
        s.write_all(&std::fs::read(real("slambook2_ch7/1.png")).unwrap()[..50_000])
            .unwrap();
        drop(s);
    }
    // One that vanishes while its frame is being processed.
    let mut s = TcpStream::connect(server.addr).unwrap();
    let frame = std::fs::read(real("slambook2_ch7/1.png")).unwrap();
    let head = format!("POST /v1/roughness HTTP/1.1\r\nHost: x\r\nContent-Type: image/png\r\nContent-Length: {}\r\n\r\n", frame.len());
    s.write_all(head.as_bytes()).unwrap();
    s.write_all(&frame).unwrap();
    drop(s);
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

#[test]
fn overload_is_refused_at_once_and_accepted_work_finishes() {
    let server = Server::start(&["--workers", "1", "--queue", "1"]);
    let url = format!("{}/v1/roughness", server.url());
    let frame = std::fs::read(real("slambook2_ch7/1.png")).unwrap();
    let outcomes = rt().block_on(async {
        let client = reqwest::Client::new();
        let order = std::sync::Arc::new(std::sync::atomic::AtomicUsize::new(0));
        // The first request alone, until the worker has started it (its batch is counted):
        // on a busy machine the burst could otherwise come before the worker takes it from
        // the queue, and find both taken.
        let tasks: Vec<_> = (0..12)
            .map(|i| {
                let (client, url, frame, order) =
                    (client.clone(), url.clone(), frame.clone(), order.clone());
                let task = tokio::spawn(async move {
                    let resp = client
                        .post(&url)
                        .header("content-type", "image/png")
                        .body(frame)
                        .send()
                        .await
                        .unwrap();
                    let status = resp.status().as_u16();
                    let retry = resp
                        .headers()
                        .get("retry-after")
                        .map(|v| v.to_str().unwrap().to_owned());
                    let body = resp.bytes().await.unwrap();
                    let finished = order.fetch_add(1, std::sync::atomic::Ordering::SeqCst);
                    (status, retry, body, finished)
                });
                if i == 0 {
                    let started = std::time::Instant::now();
                    while !String::from_utf8_lossy(&get(server.addr, "/metrics").1)
                        .contains("tre_batch_size_count 1")
                    {
                        assert!(
                            started.elapsed().as_secs() < 30,
                            "the first frame never started"
                        );
                        std::thread::sleep(std::time::Duration::from_millis(5));
                    }
                }
                task
            })
            .collect();
        let mut out = Vec::new();
        for t in tasks {
            out.push(t.await.unwrap());
        }
        out
    });
    let ok: Vec<_> = outcomes.iter().filter(|o| o.0 == 200).collect();
    let refused: Vec<_> = outcomes.iter().filter(|o| o.0 == 503).collect();
    assert_eq!(
        ok.len() + refused.len(),
        outcomes.len(),
        "only 200 and 503 expected"
    );
    assert!(
        ok.len() >= 2 && !refused.is_empty(),
        "{} ok, {} refused",
        ok.len(),
        refused.len()
    );
    for r in &refused {
        assert_eq!(r.1.as_deref(), Some("1"), "503 without Retry-After");
        let v: serde_json::Value = serde_json::from_slice(&r.2).unwrap();
        assert_eq!(v["error"]["code"], "overloaded");
    }
    for o in &ok {
        png16_values(&o.2);
    }
    // Refusals come back while accepted frames are still running: every refusal finished
    // before the last accepted frame did.
    let last_ok = ok.iter().map(|o| o.3).max().unwrap();
    assert!(refused.iter().all(|r| r.3 < last_ok));
    let metrics = String::from_utf8(get(server.addr, "/metrics").1).unwrap();
    assert!(metrics.contains(&format!(
        "tre_requests_total{{endpoint=\"roughness\",outcome=\"overloaded\"}} {}",
        refused.len()
    )));
    assert!(metrics.contains("tre_queue_capacity 1"));
}

#[test]
fn operational_endpoints() {
    let server = Server::start(&["--workers", "1"]);
    let (s, body) = get(server.addr, "/healthz");
    assert_eq!(s, 200, "{}", String::from_utf8_lossy(&body));
    assert_eq!(get(server.addr, "/readyz").0, 200);
    let (s, body) = get(server.addr, "/v1/models");
    assert_eq!(s, 200);
    let manifest: serde_json::Value = serde_json::from_slice(&body).unwrap();
    assert!(manifest["models"]["depth_net"]["sha256"].is_string());
    let (s, body) = get(server.addr, "/openapi.json");
    assert_eq!(s, 200);
    let doc: serde_json::Value = serde_json::from_slice(&body).unwrap();
    for path in [
        "/v1/roughness",
        "/v1/stream",
        "/v1/models",
        "/healthz",
        "/readyz",
        "/metrics",
        "/openapi.json",
        "/",
    ] {
        assert!(
            doc["paths"][path].is_object(),
            "{path} missing from the OpenAPI document"
        );
    }
    let (s, body) = get(server.addr, "/");
    assert_eq!(s, 200);
    assert!(String::from_utf8_lossy(&body).contains("<html"));
    let (s, body) = get(server.addr, "/metrics");
    assert_eq!(s, 200);
    let text = String::from_utf8(body).unwrap();
    for name in [
        "tre_ready 1",
        "tre_queue_depth",
        "tre_frames_dropped_total",
        "tre_batch_size_bucket",
        "tre_workers 1",
    ] {
        assert!(text.contains(name), "{name} missing from /metrics");
    }
    let (s, body) = get(server.addr, "/nope");
    assert_eq!(s, 404);
    let v: serde_json::Value = serde_json::from_slice(&body).unwrap();
    assert_eq!(v["error"]["code"], "not_found");
    let (s, body) = get(server.addr, "/v1/roughness");
    assert_eq!(s, 405);
    let v: serde_json::Value = serde_json::from_slice(&body).unwrap();
    assert_eq!(v["error"]["code"], "method_not_allowed");
    let (s, body) = get(server.addr, "/v1/stream");
    assert_eq!(s, 400, "a plain GET of the stream");
    let v: serde_json::Value = serde_json::from_slice(&body).unwrap();
    assert_eq!(v["error"]["code"], "bad_request");
}

#[test]
fn sigterm_finishes_in_flight_work_then_exits() {
    let server = Server::start(&["--workers", "1"]);
    let url = format!("{}/v1/roughness", server.url());
    let frame = std::fs::read(real("slambook2_ch7/1.png")).unwrap();
    let rt = rt();
    let pending = rt.spawn(async move { post(&url, "image/png", frame).await.status().as_u16() });
    // Wait until the frame is running (the queue has taken it), then ask the server to stop.
    let start = std::time::Instant::now();
    loop {
        let text = String::from_utf8(get(server.addr, "/metrics").1).unwrap_or_default();
        if text.contains("tre_batch_size_count 1")
            || start.elapsed() > std::time::Duration::from_secs(20)
        {
            break;
        }
        std::thread::sleep(std::time::Duration::from_millis(5));
    }
    let status = server.terminate();
    assert!(status.success(), "exit status {status}");
    assert_eq!(
        rt.block_on(pending).unwrap(),
        200,
        "the in-flight request was not finished"
    );
}

#[test]
fn clients_that_left_give_their_queue_slots_to_new_frames() {
    // One worker, a queue of one, and a short timeout: a frame that outlives its client's
    // timeout must not keep the only slot from the next client while the worker is busy.
    let server = Server::start(&[
        "--workers",
        "1",
        "--queue",
        "1",
        "--request-timeout-ms",
        "300",
        // The slow frame is 12 Mpx, over the 4 Mi default.
        "--max-pixels",
        "12000000",
    ]);
    let url = format!("{}/v1/roughness", server.url());
    let small = std::fs::read(real("slambook2_ch7/1.png")).unwrap();
    // A slow frame: 4000×3000, every output map brought back to that size.
    let big = {
        let rgb = image::open(real("slambook2_ch7/1.png")).unwrap().to_rgb8();
        let up = image::imageops::resize(&rgb, 4000, 3000, image::imageops::FilterType::Nearest);
        let mut out = std::io::Cursor::new(Vec::new());
        up.write_to(&mut out, image::ImageFormat::Jpeg).unwrap();
        out.into_inner()
    };
    let rt = rt();
    let slow_url = format!("{url}?outputs=depth,normals,slope,traversable,boundary");
    let mut slow = rt.spawn(async move {
        let resp = post(&slow_url, "image/jpeg", big).await;
        (resp.status(), resp.text().await.unwrap())
    });
    let start = std::time::Instant::now();
    while !String::from_utf8(get(server.addr, "/metrics").1)
        .unwrap_or_default()
        .contains("tre_batch_size_count 1")
    {
        assert!(
            !slow.is_finished() && start.elapsed() < std::time::Duration::from_secs(20),
            "the slow frame never started: {:?}",
            slow.is_finished().then(|| rt.block_on(&mut slow))
        );
        std::thread::sleep(std::time::Duration::from_millis(5));
    }
    rt.block_on(async {
        // Queued behind the slow frame; its client's timeout ends before the worker is free.
        let (s, code, message) = error_of(post(&url, "image/png", small.clone()).await).await;
        assert_eq!((s, code.as_str()), (503, "timeout"), "{message}");
        // Its job is still queued, but its client is gone: the next frame takes the slot.
        let resp = post(&url, "image/png", small).await;
        if resp.status().as_u16() != 200 {
            let (s, code, message) = error_of(resp).await;
            assert_eq!((s, code.as_str()), (503, "timeout"), "{message}");
        }
    });
    rt.block_on(slow).unwrap();
}

#[test]
fn a_client_that_sends_a_whole_oversize_body_first_still_reads_the_413() {
    // Like Python's http.client: write the whole request, then read the answer. 30 MB against
    // an 8 MB limit is more than loopback's socket buffers hold, so the server must read the
    // rest of the body rather than close on it.
    let server = Server::start(&["--workers", "1", "--max-body-bytes", "8000000"]);
    let body = vec![0u8; 30_000_000];
    let mut s = TcpStream::connect(server.addr).unwrap();
    s.set_read_timeout(Some(std::time::Duration::from_secs(60)))
        .unwrap();
    let head = format!(
        "POST /v1/roughness HTTP/1.1\r\nHost: x\r\nContent-Type: image/png\r\nContent-Length: {}\r\nConnection: close\r\n\r\n",
        body.len()
    );
    s.write_all(head.as_bytes()).unwrap();
    s.write_all(&body)
        .expect("the server stopped reading before the body ended");
    let mut answer = String::new();
    std::io::Read::read_to_string(&mut s, &mut answer).unwrap();
    assert!(answer.starts_with("HTTP/1.1 413"), "{answer}");
    assert!(answer.contains("\"too_large\""), "{answer}");
    rt().block_on(still_serves(&server));
}

/// The camera JSON of a real frame with only the keys the service takes: the files carry
/// notes (`source`, `licence`, ...) that `tre infer` reads past but HTTP refuses.
fn camera_part(path: &std::path::Path) -> String {
    let v: serde_json::Value = serde_json::from_slice(&std::fs::read(path).unwrap()).unwrap();
    let known = tre::server::request::CAMERA_KEYS;
    let kept: serde_json::Map<_, _> = v
        .as_object()
        .unwrap()
        .iter()
        .filter(|(k, _)| known.contains(&k.as_str()))
        .map(|(k, v)| (k.clone(), v.clone()))
        .collect();
    serde_json::Value::Object(kept).to_string()
}

/// A client that sends its headers and a few bytes of body, then nothing, holds none of the
/// `--max-concurrent` places (the only one here): other clients are served meanwhile, and it
/// hears 408 `request_timeout` at `--body-timeout-ms`.
#[test]
fn a_client_that_stalls_mid_upload_holds_no_place_and_hears_408() {
    use std::io::Read;
    let server = Server::start(&[
        "--workers",
        "1",
        "--max-concurrent",
        "1",
        "--body-timeout-ms",
        "1500",
    ]);
    let frame = std::fs::read(real("slambook2_ch7/1.png")).unwrap();
    let mut stalled = TcpStream::connect(server.addr).unwrap();
    let head = "POST /v1/roughness HTTP/1.1\r\nHost: x\r\nContent-Type: image/png\r\nContent-Length: 100000\r\n\r\n";
    stalled.write_all(head.as_bytes()).unwrap();
    stalled.write_all(&frame[..4]).unwrap();
    rt().block_on(still_serves(&server));
    stalled
        .set_read_timeout(Some(std::time::Duration::from_secs(30)))
        .unwrap();
    let mut answer = Vec::new();
    let _ = stalled.read_to_end(&mut answer);
    let answer = String::from_utf8_lossy(&answer);
    assert!(answer.starts_with("HTTP/1.1 408"), "{answer}");
    assert!(
        answer.contains("\"request_timeout\"") && answer.contains("--body-timeout-ms"),
        "{answer}"
    );
    rt().block_on(still_serves(&server));
}

/// Eighty connections sending a body at one byte a second (the defaults: 64 places) do not
/// stop another client's frame: it is answered 200 while they trickle, and the trickling
/// uploads end with 408 (at the end of the first `--min-body-rate` window, 5 s).
#[test]
fn eighty_trickling_uploads_do_not_starve_a_ready_request() {
    let server = Server::start(&["--workers", "1", "--body-timeout-ms", "6000"]);
    let head = "POST /v1/roughness HTTP/1.1\r\nHost: x\r\nContent-Type: image/png\r\nContent-Length: 100000\r\n\r\n";
    let mut trickles: Vec<TcpStream> = (0..80)
        .map(|_| {
            let mut t = TcpStream::connect(server.addr).unwrap();
            t.write_all(head.as_bytes()).unwrap();
            t
        })
        .collect();
    let stop = std::sync::Arc::new(std::sync::atomic::AtomicBool::new(false));
    let feeder = {
        let mut writers: Vec<TcpStream> = trickles.iter().map(|t| t.try_clone().unwrap()).collect();
        let stop = stop.clone();
        std::thread::spawn(move || {
            while !stop.load(std::sync::atomic::Ordering::Relaxed) {
                for w in &mut writers {
                    let _ = w.write_all(b"x");
                }
                std::thread::sleep(std::time::Duration::from_secs(1));
            }
        })
    };
    std::thread::sleep(std::time::Duration::from_secs(1));
    let started = std::time::Instant::now();
    rt().block_on(still_serves(&server));
    // Generous: the frame itself takes well under a second; the trickle lasts 6 s.
    assert!(
        started.elapsed() < std::time::Duration::from_secs(5),
        "a ready frame waited {:?} behind trickling uploads",
        started.elapsed()
    );
    let mut first = trickles.remove(0);
    first
        .set_read_timeout(Some(std::time::Duration::from_secs(30)))
        .unwrap();
    let mut answer = [0u8; 12];
    std::io::Read::read_exact(&mut first, &mut answer).unwrap();
    assert_eq!(
        &answer,
        b"HTTP/1.1 408",
        "{}",
        String::from_utf8_lossy(&answer)
    );
    stop.store(true, std::sync::atomic::Ordering::Relaxed);
    feeder.join().unwrap();
}

/// An RGB PNG of `w`×`h` that does not compress (a deterministic noise), about 3 B per pixel.
fn noise_png(w: u32, h: u32) -> Vec<u8> {
    let mut state = 0x2545_f491_u32;
    let img = image::RgbImage::from_fn(w, h, |_, _| {
        state ^= state << 13;
        state ^= state >> 17;
        state ^= state << 5;
        let [a, b, c, _] = state.to_le_bytes();
        image::Rgb([a, b, c])
    });
    let mut out = Vec::new();
    image::DynamicImage::ImageRgb8(img)
        .write_to(&mut std::io::Cursor::new(&mut out), image::ImageFormat::Png)
        .unwrap();
    out
}

/// Sends `body` as a PNG upload at `chunk` bytes every `every` and returns the answer, read as
/// it comes (the server may answer and close before the body is all sent).
fn paced_upload(server: &Server, body: &[u8], chunk: usize, every: std::time::Duration) -> String {
    use std::io::Read;
    let mut tcp = TcpStream::connect(server.addr).unwrap();
    let mut reader = tcp.try_clone().unwrap();
    let reading = std::thread::spawn(move || {
        let mut answer = Vec::new();
        let _ = reader.read_to_end(&mut answer);
        String::from_utf8_lossy(&answer).into_owned()
    });
    let head = format!(
        "POST /v1/roughness?mode=rgb&normals=ls HTTP/1.1\r\nHost: x\r\nContent-Type: image/png\r\nContent-Length: {}\r\nConnection: close\r\n\r\n",
        body.len()
    );
    tcp.write_all(head.as_bytes()).unwrap();
    for piece in body.chunks(chunk) {
        if reading.is_finished() || tcp.write_all(piece).is_err() {
            break;
        }
        std::thread::sleep(every);
    }
    reading.join().unwrap()
}

/// `--min-body-rate` (1 KiB/s by default, over 5 s windows): an upload at about 100 B/s hears
/// 408 naming the option after one window, long before `--body-timeout-ms` (60 s here); one at
/// about 2.5 KiB/s, slow but above the rate, lasting beyond a window, is answered 200.
#[test]
fn a_body_below_the_minimum_rate_hears_408_and_one_above_it_is_served() {
    let server = Server::start(&["--workers", "1", "--body-timeout-ms", "60000"]);
    let frame = noise_png(96, 64);
    assert!(frame.len() > 15_000, "{} bytes", frame.len());
    let started = std::time::Instant::now();
    let (slow, steady) = std::thread::scope(|s| {
        let slow =
            s.spawn(|| paced_upload(&server, &frame, 20, std::time::Duration::from_millis(200)));
        let steady =
            s.spawn(|| paced_upload(&server, &frame, 500, std::time::Duration::from_millis(200)));
        (slow.join().unwrap(), steady.join().unwrap())
    });
    assert!(slow.starts_with("HTTP/1.1 408"), "{slow}");
    assert!(
        slow.contains("\"request_timeout\"") && slow.contains("--min-body-rate"),
        "{slow}"
    );
    assert!(steady.starts_with("HTTP/1.1 200"), "{steady}");
    assert!(
        started.elapsed() < std::time::Duration::from_secs(30),
        "took {:?}",
        started.elapsed()
    );
}

/// Posts `frame` for `query` over a socket with a receive buffer of `recv_buffer` bytes (so that
/// a large answer fills the connection) and returns the socket without reading.
async fn post_unread(
    server: &Server,
    query: &str,
    frame: &[u8],
    recv_buffer: u32,
) -> tokio::net::TcpStream {
    use tokio::io::AsyncWriteExt;
    let socket = tokio::net::TcpSocket::new_v4().unwrap();
    socket.set_recv_buffer_size(recv_buffer).unwrap();
    let mut tcp = socket.connect(server.addr).await.unwrap();
    let head = format!(
        "POST /v1/roughness?{query} HTTP/1.1\r\nHost: x\r\nContent-Type: image/png\r\nContent-Length: {}\r\n\r\n",
        frame.len()
    );
    tcp.write_all(head.as_bytes()).await.unwrap();
    tcp.write_all(frame).await.unwrap();
    tcp
}

/// Reads an HTTP answer from `tcp`, `chunk` bytes at a time with `pause` before each read,
/// until its body is complete or the connection ends: (answer bytes, whether complete).
async fn read_answer(
    tcp: &mut tokio::net::TcpStream,
    chunk: usize,
    pause: std::time::Duration,
) -> (Vec<u8>, bool) {
    use tokio::io::AsyncReadExt;
    let mut answer = Vec::new();
    let mut buf = vec![0u8; chunk];
    loop {
        tokio::time::sleep(pause).await;
        let read = tokio::time::timeout(std::time::Duration::from_secs(30), tcp.read(&mut buf));
        match read.await.expect("no byte and no end within 30 s") {
            Ok(0) | Err(_) => return (answer, false),
            Ok(n) => answer.extend_from_slice(&buf[..n]),
        }
        let text = String::from_utf8_lossy(&answer);
        if let Some(end) = text.find("\r\n\r\n") {
            let length: usize = text[..end]
                .lines()
                .find_map(|l| l.strip_prefix("content-length: "))
                .expect("a content-length")
                .parse()
                .unwrap();
            if answer.len() >= end + 4 + length {
                return (answer, true);
            }
        }
    }
}

/// A client that stops reading its answer, such as a hung process with its socket open, once
/// kept its connection and the answer in it (here 640×480 float maps, about 7 MB, more than the
/// system's socket buffers hold) until the server stopped, and held up its shutdown for the
/// whole grace time. Now the connection ends once the client has taken nothing for
/// `--stall-timeout-ms`, so the answer it reads later is cut short; a client that reads slowly
/// but steadily still gets all of it.
#[test]
fn a_client_that_stops_reading_its_answer_loses_the_connection_and_a_slow_one_does_not() {
    let server = Server::start(&["--workers", "1", "--stall-timeout-ms", "1500"]);
    let frame = std::fs::read(real("slambook2_ch7/1.png")).unwrap();
    rt().block_on(async {
        let big = "mode=rgb&normals=ls&format=npy&outputs=depth,normals,slope";
        let mut stuck = post_unread(&server, big, &frame, 4096).await;
        tokio::time::sleep(std::time::Duration::from_secs(5)).await;
        let (answer, complete) = read_answer(&mut stuck, 1 << 20, Default::default()).await;
        assert!(answer.starts_with(b"HTTP/1.1 200"));
        assert!(
            !complete,
            "all {} bytes arrived after a 5 s stall",
            answer.len()
        );
        // Slow but steady (at most 256 KiB every 0.2 s, about 6 s for the same answer): the
        // server waits on it throughout, never 1.5 s without progress.
        let mut slow = post_unread(&server, big, &frame, 256 << 10).await;
        let pause = std::time::Duration::from_millis(200);
        let (answer, complete) = read_answer(&mut slow, 256 << 10, pause).await;
        assert!(
            complete,
            "a slow reader was cut off after {} bytes",
            answer.len()
        );
        still_serves(&server).await;
    });
}

/// Whether the server closes `tcp` within `within` while it is sent one byte of `bytes` every
/// 0.2 s (nothing once they run out). A server that answers instead is a failure.
fn closed_within(mut tcp: TcpStream, bytes: &[u8], within: std::time::Duration) -> bool {
    use std::io::Read;
    let start = std::time::Instant::now();
    tcp.set_read_timeout(Some(std::time::Duration::from_millis(200)))
        .unwrap();
    let mut sent = 0;
    while start.elapsed() < within {
        if sent < bytes.len() && tcp.write_all(&bytes[sent..=sent]).is_ok() {
            sent += 1;
        }
        let mut buf = [0u8; 256];
        match tcp.read(&mut buf) {
            Ok(0) => return true,
            Ok(n) => panic!("an answer: {}", String::from_utf8_lossy(&buf[..n])),
            Err(e) if e.kind() == std::io::ErrorKind::WouldBlock => {}
            Err(e) if e.kind() == std::io::ErrorKind::TimedOut => {}
            Err(_) => return true,
        }
    }
    false
}

/// Request headers sent a byte at a time (slowloris), and a connection opened and left idle,
/// were once kept until the server stopped: a task and a file descriptor each, so enough of
/// them exhaust the process's descriptors. Now the headers must arrive within
/// `--header-timeout-ms`: a client that sent part of them hears 408, an idle kept-alive
/// connection is closed without a word; requests that arrive in time are served, on new and
/// kept-alive connections alike.
#[test]
fn request_headers_have_a_deadline_and_idle_connections_are_closed() {
    use std::io::Read;
    let server = Server::start(&["--workers", "1", "--header-timeout-ms", "1500"]);
    let within = std::time::Duration::from_secs(8);
    let head = b"POST /v1/roughness HTTP/1.1\r\nHost: x\r\nContent-Type: image/png\r\nX-Pad: aaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaa";
    let mut trickling = TcpStream::connect(server.addr).unwrap();
    let start = std::time::Instant::now();
    trickling
        .set_read_timeout(Some(std::time::Duration::from_millis(200)))
        .unwrap();
    let mut answer = Vec::new();
    for b in head.iter().cycle() {
        assert!(
            start.elapsed() < within,
            "headers sent a byte every 0.2 s still held the connection 8 s on"
        );
        let _ = trickling.write_all(&[*b]);
        let mut buf = [0u8; 512];
        match trickling.read(&mut buf) {
            Ok(0) => break,
            Ok(n) => answer.extend_from_slice(&buf[..n]),
            Err(e)
                if matches!(
                    e.kind(),
                    std::io::ErrorKind::WouldBlock | std::io::ErrorKind::TimedOut
                ) => {}
            Err(_) => break,
        }
    }
    let answer = String::from_utf8_lossy(&answer);
    assert!(answer.starts_with("HTTP/1.1 408"), "{answer}");
    assert!(answer.contains("--header-timeout-ms"), "{answer}");
    let idle = TcpStream::connect(server.addr).unwrap();
    assert!(
        closed_within(idle, b"", within),
        "an idle connection was still open 8 s on"
    );
    // Two requests 1 s apart on one kept-alive connection are both served.
    rt().block_on(async {
        let client = reqwest::Client::new();
        for _ in 0..2 {
            let resp = client.get(format!("{}/healthz", server.url())).send().await;
            assert_eq!(resp.unwrap().status().as_u16(), 200);
            tokio::time::sleep(std::time::Duration::from_secs(1)).await;
        }
        still_serves(&server).await;
    });
}

/// Connections were once unlimited in number: each held a task and a file descriptor until its
/// deadlines ran out, so enough of them, idle, exhausted the process's descriptors and left
/// the server unable to take any. Over `--max-connections` a request is now answered 503
/// `overloaded` with `Retry-After` at once, past twice the limit a connection is closed
/// unanswered, and once the holders leave the server takes connections again.
#[test]
fn connections_over_the_limit_are_answered_503_at_once() {
    let server = Server::start(&["--workers", "1", "--max-connections", "2"]);
    // Two kept-alive connections that have been served hold both places. (A connection the
    // server is still closing, such as the start-up probe's, may hold one for a moment: a
    // holder refused then is opened again.)
    let mut early = 0;
    let holders: Vec<TcpStream> = (0..2)
        .map(|_| loop {
            use std::io::Read;
            let mut tcp = TcpStream::connect(server.addr).unwrap();
            tcp.set_read_timeout(Some(std::time::Duration::from_secs(5)))
                .unwrap();
            tcp.write_all(b"GET /healthz HTTP/1.1\r\nHost: x\r\n\r\n")
                .unwrap();
            let mut raw = Vec::new();
            let mut buf = [0u8; 512];
            while !raw.ends_with(b"}") {
                let n = tcp.read(&mut buf).unwrap();
                assert!(n > 0, "closed: {}", String::from_utf8_lossy(&raw));
                raw.extend_from_slice(&buf[..n]);
            }
            if raw.starts_with(b"HTTP/1.1 200") {
                break tcp;
            }
            early += 1;
            std::thread::sleep(std::time::Duration::from_millis(50));
        })
        .collect();
    fn refused_reply(tcp: &mut TcpStream) -> Vec<u8> {
        use std::io::Read;
        tcp.set_read_timeout(Some(std::time::Duration::from_secs(5)))
            .unwrap();
        let mut raw = Vec::new();
        let _ = tcp.read_to_end(&mut raw);
        raw
    }
    let refused = |tcp: &mut TcpStream| -> Option<Vec<u8>> {
        let req = b"GET /healthz HTTP/1.1\r\nHost: x\r\n\r\n";
        tcp.write_all(req).ok()?;
        Some(refused_reply(tcp))
    };
    // Two more get the answer (and keep the refusals' places while they are open); a fifth
    // finds both kinds of place taken and is closed unanswered.
    let mut waiting: Vec<TcpStream> = (0..3)
        .map(|_| TcpStream::connect(server.addr).unwrap())
        .collect();
    std::thread::sleep(std::time::Duration::from_millis(300));
    let answers: Vec<String> = waiting
        .iter_mut()
        .map(|t| String::from_utf8_lossy(&refused(t).unwrap_or_default()).into_owned())
        .collect();
    for answer in &answers[..2] {
        assert!(answer.starts_with("HTTP/1.1 503"), "{answer}");
        assert!(answer.contains("retry-after: 1"), "{answer}");
        assert!(answer.contains("\"code\":\"overloaded\""), "{answer}");
        assert!(answer.contains("--max-connections"), "{answer}");
    }
    assert_eq!(answers[2], "", "past twice the limit: closed unanswered");
    drop(waiting);
    // A client that sends its whole 3 MB request before reading (as Python's http.client does)
    // gets the answer too, not a broken pipe: the body is read and dropped first.
    std::thread::sleep(std::time::Duration::from_millis(300));
    let mut eager = TcpStream::connect(server.addr).unwrap();
    let body = vec![7u8; 3 << 20];
    let head = format!(
        "POST /v1/roughness HTTP/1.1\r\nHost: x\r\nContent-Type: image/png\r\nContent-Length: {}\r\n\r\n",
        body.len()
    );
    eager.write_all(head.as_bytes()).unwrap();
    eager
        .write_all(&body)
        .expect("the refused request's body was not read");
    let answer = String::from_utf8_lossy(&refused_reply(&mut eager)).into_owned();
    assert!(answer.starts_with("HTTP/1.1 503"), "{answer}");
    assert!(answer.contains("\"code\":\"overloaded\""), "{answer}");
    drop(holders);
    // The places are free again: the server serves.
    let start = std::time::Instant::now();
    while get(server.addr, "/healthz").0 != 200 {
        early += 1;
        assert!(
            start.elapsed() < std::time::Duration::from_secs(5),
            "the places were not freed"
        );
        std::thread::sleep(std::time::Duration::from_millis(50));
    }
    let metrics = String::from_utf8(get(server.addr, "/metrics").1).unwrap();
    let refused_total = format!("tre_connections_refused_total {}\n", 4 + early);
    assert!(metrics.contains(&refused_total), "{metrics}");
    assert!(metrics.contains("tre_connections_open 1\n"), "{metrics}");
    rt().block_on(still_serves(&server));
}

/// The OpenAPI document is what the server does: every query parameter it lists is taken (all
/// at once, with values its schema allows) and one it does not list is refused; every `format`
/// it enumerates and every body type it lists gives a map; and it is valid OpenAPI 3.0, where
/// `exclusiveMinimum` is a flag beside `minimum` (a number there is 3.1, which 3.0 tools
/// reject).
#[test]
fn the_openapi_document_matches_what_the_server_takes() {
    let server = Server::start(&["--workers", "1"]);
    let (s, body) = get(server.addr, "/openapi.json");
    assert_eq!(s, 200);
    let doc: serde_json::Value = serde_json::from_slice(&body).unwrap();
    assert!(doc["openapi"].as_str().unwrap().starts_with("3.0."));
    fn walk(v: &serde_json::Value, bad: &mut Vec<String>) {
        match v {
            serde_json::Value::Object(m) => {
                for (k, v) in m {
                    if k.starts_with("exclusiveM") && !v.is_boolean() {
                        bad.push(format!("{k}: {v}"));
                    }
                    walk(v, bad);
                }
            }
            serde_json::Value::Array(a) => a.iter().for_each(|v| walk(v, bad)),
            _ => {}
        }
    }
    let mut not_3_0 = Vec::new();
    walk(&doc, &mut not_3_0);
    assert!(not_3_0.is_empty(), "not OpenAPI 3.0: {not_3_0:?}");

    let op = &doc["paths"]["/v1/roughness"]["post"];
    let examples = [
        ("format", "png16"),
        ("mode", "rgb"),
        ("seed", "7"),
        ("normals", "ls"),
        ("dsac_hypotheses", "4"),
        ("preview_max_cm", "4"),
        ("max_roughness_cm", "3"),
        ("max_slope_deg", "25"),
        ("outputs", "slope"),
        ("fx", "525"),
        ("fy", "525"),
        ("cx", "319.5"),
        ("cy", "239.5"),
        ("pitch_deg", "50"),
        ("height_m", "0.8"),
        ("depth_scale", "1000"),
        ("sensor", "kinect_v1"),
    ];
    let listed: Vec<&str> = op["parameters"]
        .as_array()
        .unwrap()
        .iter()
        .map(|p| p["name"].as_str().unwrap())
        .collect();
    let mut named: Vec<&str> = examples.iter().map(|(n, _)| *n).collect();
    let mut sorted = listed.clone();
    sorted.sort_unstable();
    named.sort_unstable();
    assert_eq!(sorted, named, "the document's query parameters");
    let frame = std::fs::read(real("slambook2_ch7/1.png")).unwrap();
    let url = |query: &str| format!("{}/v1/roughness?{query}", server.url());
    let all: Vec<String> = examples.iter().map(|(n, v)| format!("{n}={v}")).collect();
    rt().block_on(async {
        let resp = post(&url(&all.join("&")), "image/png", frame.clone()).await;
        assert_eq!(
            resp.status().as_u16(),
            200,
            "every documented parameter at once"
        );
        let resp = post(
            &url("normals=ls&colour_map=turbo"),
            "image/png",
            frame.clone(),
        )
        .await;
        let (status, code, message) = error_of(resp).await;
        assert_eq!((status, code.as_str()), (400, "bad_request"), "{message}");

        let formats = op["parameters"]
            .as_array()
            .unwrap()
            .iter()
            .find(|p| p["name"] == "format")
            .unwrap()["schema"]["enum"]
            .as_array()
            .unwrap()
            .clone();
        assert!(formats.len() >= 3);
        for f in formats {
            let f = f.as_str().unwrap();
            let resp = post(
                &url(&format!("normals=ls&format={f}")),
                "image/png",
                frame.clone(),
            )
            .await;
            assert_eq!(resp.status().as_u16(), 200, "format={f}");
        }
        let types = op["requestBody"]["content"].as_object().unwrap();
        assert!(types.contains_key("image/png") && types.contains_key("image/jpeg"));
        for t in types.keys().filter(|t| !t.starts_with("multipart/")) {
            let resp = post(&url("normals=ls"), t, frame.clone()).await;
            assert_eq!(resp.status().as_u16(), 200, "Content-Type {t}");
        }
    });
}

/// Long thin images are refused from their header at once, naming the limit: the 49 KB kind
/// of PNG that declares 16777216×1 (once 11 s of resizing) gets 413 `--max-side`, a 8192×2
/// one 422 `--max-aspect`; a camera part with an unknown key or a height of 1e300 m is 422.
#[test]
fn long_thin_images_and_implausible_cameras_are_refused_at_once() {
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
            (r#", "licence": "MIT"}"#, "unknown key \"licence\""),
            (r#", "height_m": 1e300}"#, "height_m"),
            (r#", "pitch_deg": 135}"#, "pitch_deg"),
            (r#", "sensor": "a free-text description"}"#, ""),
        ] {
            let form = Form::new()
                .part("rgb", Part::bytes(frame.clone()).file_name("1.png"))
                .part("camera", Part::text(format!("{camera}{extra}")));
            let resp = reqwest::Client::new()
                .post(&url)
                .multipart(form)
                .send()
                .await
                .unwrap();
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

/// With `--api-key`, every route but `/healthz` and `/readyz` wants the Bearer key (401
/// otherwise, with `WWW-Authenticate`), and foreign browser origins are refused (403) unless
/// on `--allow-origin`, whose preflights are answered and answers carry their allow-origin.
#[test]
fn the_api_key_and_the_origin_allow_list_guard_every_route() {
    let key = "0123456789abcdef0123";
    let ops = "https://ops.example";
    let server = Server::start(&["--workers", "1", "--api-key", key, "--allow-origin", ops]);
    let frame = std::fs::read(real("slambook2_ch7/1.png")).unwrap();
    let url = format!("{}/v1/roughness?mode=rgb", server.url());
    rt().block_on(async {
        let client = reqwest::Client::new();
        for path in ["/healthz", "/readyz"] {
            assert_eq!(get(server.addr, path).0, 200, "{path}");
        }
        for path in ["/metrics", "/v1/models", "/openapi.json", "/"] {
            assert_eq!(get(server.addr, path).0, 401, "{path}");
        }
        let send = |auth: Option<String>, origin: Option<&str>| {
            let mut req = client
                .post(&url)
                .header("content-type", "image/png")
                .header("x-request-id", "robot-7.frame-1")
                .body(frame.clone());
            if let Some(a) = auth {
                req = req.header("authorization", a);
            }
            if let Some(o) = origin {
                req = req.header("origin", o);
            }
            req.send()
        };
        let resp = send(None, None).await.unwrap();
        assert_eq!(resp.headers()["www-authenticate"], "Bearer realm=\"tre\"");
        assert_eq!(resp.headers()["x-request-id"], "robot-7.frame-1");
        assert_eq!(error_of(resp).await.1, "unauthorized");
        let resp = send(Some("Bearer wrong-key-of-some-length".into()), None)
            .await
            .unwrap();
        assert_eq!(error_of(resp).await.0, 401);
        let bearer = format!("Bearer {key}");
        let resp = send(Some(bearer.clone()), None).await.unwrap();
        assert_eq!(resp.status().as_u16(), 200);
        assert!(resp.headers().get("access-control-allow-origin").is_none());
        let resp = send(Some(bearer.clone()), Some("http://evil.example"))
            .await
            .unwrap();
        assert_eq!(error_of(resp).await.1, "forbidden");
        let resp = send(Some(bearer.clone()), Some(ops)).await.unwrap();
        assert_eq!(resp.status().as_u16(), 200);
        assert_eq!(resp.headers()["access-control-allow-origin"], ops);
        assert!(resp.headers()["access-control-expose-headers"]
            .to_str()
            .unwrap()
            .contains("server-timing"));
        let preflight = |origin: &'static str| {
            client
                .request(reqwest::Method::OPTIONS, &url)
                .header("origin", origin)
                .header("access-control-request-method", "POST")
                .header(
                    "access-control-request-headers",
                    "authorization, content-type",
                )
                .send()
        };
        let resp = preflight("https://ops.example").await.unwrap();
        assert_eq!(resp.status().as_u16(), 204);
        assert_eq!(resp.headers()["access-control-allow-origin"], ops);
        assert!(resp.headers()["access-control-allow-headers"]
            .to_str()
            .unwrap()
            .contains("authorization"));
        assert_eq!(
            preflight("http://evil.example")
                .await
                .unwrap()
                .status()
                .as_u16(),
            403
        );
        // The stream upgrade: no key 401, a foreign origin 403, the key 101.
        use tokio_tungstenite::tungstenite::client::IntoClientRequest;
        let ws_url = format!("ws://{}/v1/stream", server.addr);
        for (auth, origin, status) in [
            (None, None, 401),
            (Some(bearer.as_str()), Some("http://evil.example"), 403),
            (Some(bearer.as_str()), None, 101),
        ] {
            let mut req = ws_url.as_str().into_client_request().unwrap();
            if let Some(a) = auth {
                req.headers_mut()
                    .insert("authorization", a.parse().unwrap());
            }
            if let Some(o) = origin {
                req.headers_mut().insert("origin", o.parse().unwrap());
            }
            let got = match tokio_tungstenite::connect_async(req).await {
                Ok((_, resp)) => resp.status().as_u16(),
                Err(tokio_tungstenite::tungstenite::Error::Http(resp)) => resp.status().as_u16(),
                Err(e) => panic!("{e}"),
            };
            assert_eq!(got, status, "{auth:?} {origin:?}");
        }
    });
}
