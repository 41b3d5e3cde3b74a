//! Answers equal `tre infer` (RGB, RGB-D, DSAC hypotheses), formats and extra outputs, the
//! operational endpoints, and the OpenAPI document against what the server takes.

use super::*;

#[test]
fn answers_equal_tre_infer_in_rgb_and_rgbd() {
    crate::common::skip_unless_shared!("data/real-rgbd");
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
        assert_map_headers(resp.headers());
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
            .part(
                "camera",
                Part::text(std::fs::read_to_string(&camera_path).unwrap()),
            );
        let resp = post_form(&format!("{}/v1/roughness?seed=3", server.url()), form).await;
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

/// The headers of a 640×480 frame's map: scale, image and working size, and the worker's stages
/// in `Server-Timing`, the wait for a worker and decoding first, encoding last.
fn assert_map_headers(h: &reqwest::header::HeaderMap) {
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
    // The wait for a worker, then the worker's whole job: decoding first, encoding (and any
    // extra maps) last.
    let stages: Vec<&str> = timing
        .split(", ")
        .map(|s| s.split(';').next().unwrap())
        .collect();
    assert_eq!(
        (stages.first(), stages.get(1), stages.last()),
        (Some(&"queue"), Some(&"decode"), Some(&"encode")),
        "{timing}"
    );
}

#[test]
fn serve_dsac_hypotheses_sets_the_frames_default_and_is_checked() {
    crate::common::skip_unless_shared!("data/real-rgbd");
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

/// The OpenAPI document is what the server does: every query parameter it lists is taken (all
/// at once, with values its schema allows) and one it does not list is refused; every `format`
/// it enumerates and every body type it lists gives a map; and it is valid OpenAPI 3.0, where
/// `exclusiveMinimum` is a flag beside `minimum` (a number there is 3.1, which 3.0 tools
/// reject).
#[test]
fn the_openapi_document_matches_what_the_server_takes() {
    crate::common::skip_unless_shared!("data/real-rgbd");
    let server = Server::start(&["--workers", "1"]);
    let (s, body) = get(server.addr, "/openapi.json");
    assert_eq!(s, 200);
    let doc: serde_json::Value = serde_json::from_slice(&body).unwrap();
    assert!(doc["openapi"].as_str().unwrap().starts_with("3.0."));
    let mut not_3_0 = Vec::new();
    walk(&doc, &mut not_3_0);
    assert!(not_3_0.is_empty(), "not OpenAPI 3.0: {not_3_0:?}");

    let op = &doc["paths"]["/v1/roughness"]["post"];
    let listed: Vec<&str> = op["parameters"]
        .as_array()
        .unwrap()
        .iter()
        .map(|p| p["name"].as_str().unwrap())
        .collect();
    let mut named: Vec<&str> = EXAMPLES.iter().map(|(n, _)| *n).collect();
    let mut sorted = listed.clone();
    sorted.sort_unstable();
    named.sort_unstable();
    assert_eq!(sorted, named, "the document's query parameters");
    let frame = std::fs::read(real("slambook2_ch7/1.png")).unwrap();
    rt().block_on(documented_requests_are_served(&server, op, &frame));
}

/// Every `exclusiveMinimum` or `exclusiveMaximum` under `v` that is not a flag (OpenAPI 3.1's
/// form), added to `bad`.
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

/// A value its schema allows for every query parameter of `POST /v1/roughness`.
const EXAMPLES: [(&str, &str); 17] = [
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

/// Every parameter of the document `op` at once is taken, one it does not list is refused, and
/// every `format` it enumerates and every body type it lists gives a map.
async fn documented_requests_are_served(server: &Server, op: &serde_json::Value, frame: &[u8]) {
    let frame = frame.to_vec();
    let url = |query: &str| format!("{}/v1/roughness?{query}", server.url());
    let all: Vec<String> = EXAMPLES.iter().map(|(n, v)| format!("{n}={v}")).collect();
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
}

/// With dynamic batching (`--batch-max`), frames that arrive together share each net's runs,
/// and every answer is still the frame's own: `tre infer`'s map, up to the last digits of the
/// batched convolutions (at most 1% of pixels off, by at most 1 mm); and the server still stops
/// cleanly.
#[test]
fn batched_answers_equal_tre_infer() {
    crate::common::skip_unless_shared!("data/real-rgbd");
    let server = Server::start(&[
        "--workers",
        "2",
        "--batch-max",
        "2",
        "--batch-delay-ms",
        "300",
    ]);
    let paths = [real("slambook2_ch7/1.png"), real("slambook2_ch7/2.png")];
    let served = rt().block_on(async {
        let url = format!("{}/v1/roughness?mode=rgb", server.url());
        let posts = paths.iter().map(|p| {
            let (url, frame) = (url.clone(), std::fs::read(p).unwrap());
            tokio::spawn(async move { post(&url, "image/png", frame).await })
        });
        let mut out = Vec::new();
        for p in posts.collect::<Vec<_>>() {
            let resp = p.await.unwrap();
            assert_eq!(resp.status().as_u16(), 200);
            out.push(png16_values(&resp.bytes().await.unwrap()));
        }
        out
    });
    for (path, (w, h, got)) in paths.iter().zip(served) {
        let (rw, rh, want) = infer_png16(&[path.to_str().unwrap(), "--mode", "rgb"]);
        assert_eq!((w, h), (rw, rh));
        let off = got
            .iter()
            .zip(&want)
            .filter(|(g, w)| g.abs_diff(**w) > 0)
            .count();
        let far = got.iter().zip(&want).map(|(g, w)| g.abs_diff(*w)).max();
        assert!(
            off * 100 <= got.len(),
            "{off} of {} pixels differ",
            got.len()
        );
        assert!(far <= Some(10), "largest difference {far:?} (0.1 mm units)");
    }
    let (_, metrics) = get(server.addr, "/metrics");
    let metrics = String::from_utf8(metrics).unwrap();
    let sample = |name: &str| -> f64 {
        let line = metrics.lines().find(|l| l.starts_with(name)).unwrap();
        line.rsplit(' ').next().unwrap().parse().unwrap()
    };
    // Warm-up runs one batch of 1 per net and mode and worker; the two frames met at least once.
    let (sum, count) = (sample("tre_batch_size_sum"), sample("tre_batch_size_count"));
    assert!(
        sum > count,
        "no batch of more than one frame: sum {sum}, count {count}"
    );
    // The models' threads end with the workers: SIGTERM stops the server cleanly.
    let status = server.terminate();
    assert!(status.success(), "exit status {status}");
}
