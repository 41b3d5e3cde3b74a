//! The sensor maps through `tre infer`, HTTP and the stream.

use super::*;

/// The TUM frame's depth and camera (whose `sensor` is free text, naming no preset).
/// `tre annotate`'s roughness of the TUM frame's depth as the service's 16-bit PNG values.
/// The geometric mode's map of the TUM frame under the Kinect v1 model, computed in process.
fn terrain_png16() -> Vec<u16> {
    use tre::pipeline::{FrameInput, Mode, Pipeline, PipelineConfig};
    let (depth, camera) = tum();
    let (cam, k) = tre::io::read_camera(&camera).unwrap();
    let depth_m = tre::io::read_depth(&depth, cam.depth_scale.unwrap()).unwrap();
    let input = FrameInput {
        depth_m: Some(depth_m),
        intrinsics: Some(k),
        sensor: Some(SensorNoise::Preset(SensorPreset::KinectV1)),
        ..FrameInput::default()
    };
    let cfg = PipelineConfig::for_mode(Mode::Geometric);
    let out = Pipeline::new(None).run(&input, &cfg).unwrap();
    let hazards = (out.roughness_m.as_slice().iter())
        .filter(|&&r| r >= 0.1)
        .count();
    assert!(hazards > 1000, "the frame has drops: {hazards}");
    tre::io::roughness_png16(&out.roughness_m).into_raw()
}

fn tum() -> (PathBuf, PathBuf) {
    (
        common::real("slambook2_ch7/1_depth.png"),
        common::real("slambook2_ch7/intrinsics.json"),
    )
}

fn infer(args: &[&str], out: &Path) -> std::process::Output {
    Command::new(env!("CARGO_BIN_EXE_tre"))
        .current_dir(env!("CARGO_MANIFEST_DIR"))
        .arg("infer")
        .args(args)
        .args(["-o", out.to_str().unwrap()])
        .output()
        .unwrap()
}

/// The values of an 8-bit three-state PNG, checked to be 0, 1 or 2.
fn traversal_values(png: &[u8]) -> [usize; 3] {
    let img = image::load_from_memory(png).unwrap();
    assert_eq!(img.color(), image::ColorType::L8);
    let mut c = [0; 3];
    for v in img.to_luma8().into_raw() {
        assert!(v <= 2, "traversal value {v}");
        c[v as usize] += 1;
    }
    c
}

#[test]
fn tre_infer_writes_the_uncertainty_and_three_state_maps_with_a_sensor() {
    crate::common::skip_unless_shared!("data/real-rgbd");
    let (depth, camera) = tum();
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("r.png");
    let base = [
        "--depth",
        depth.to_str().unwrap(),
        "--camera",
        camera.to_str().unwrap(),
    ];
    // The camera's free-text sensor: roughness only, and a note naming the presets.
    let o = infer(&base, &out);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(
        err.contains("names no noise model") && err.contains("kinect_v1"),
        "{err}"
    );
    assert!(!dir.path().join("r_traversal.png").exists());
    // --sensor overrides it.
    let o = infer(&[&base[..], &["--sensor", "kinect_v1"]].concat(), &out);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let stdout = String::from_utf8_lossy(&o.stdout);
    assert!(
        stdout.contains("sensor kinect_v1") && stdout.contains("% unknown"),
        "{stdout}"
    );
    let (w, h, u) =
        common::png16_values(&std::fs::read(dir.path().join("r_uncertainty.png")).unwrap());
    assert_eq!((w, h), (640, 480));
    // Grey + alpha: some valid pixels with a positive uncertainty, holes masked.
    assert!(u.chunks(2).any(|p| p[1] == u16::MAX && p[0] > 0));
    assert!(u.chunks(2).any(|p| p[1] == 0));
    let c = traversal_values(&std::fs::read(dir.path().join("r_traversal.png")).unwrap());
    assert!(c.iter().all(|&n| n > 1000), "every state present: {c:?}");
    let preview = image::open(dir.path().join("r_traversal_preview.png")).unwrap();
    assert_eq!(preview.color(), image::ColorType::Rgb8);
    // A bad sensor name is refused, naming the presets.
    let o = infer(&[&base[..], &["--sensor", "kinect"]].concat(), &out);
    assert!(!o.status.success());
    assert!(String::from_utf8_lossy(&o.stderr).contains("realsense_d435"));
}

/// Splits a multipart/mixed body into (part name, bytes).
fn parts(content_type: &str, body: &[u8]) -> Vec<(String, Vec<u8>)> {
    let boundary = format!(
        "--{}",
        content_type
            .split("boundary=")
            .nth(1)
            .unwrap()
            .trim_matches('"')
    );
    let find = |hay: &[u8], needle: &[u8], from: usize| {
        hay[from..]
            .windows(needle.len())
            .position(|w| w == needle)
            .map(|i| i + from)
    };
    let mut out = vec![];
    let mut at = find(body, boundary.as_bytes(), 0).unwrap();
    while let Some(head_end) = find(body, b"\r\n\r\n", at) {
        let head = String::from_utf8_lossy(&body[at..head_end]).into_owned();
        let Some(end) = find(body, format!("\r\n{boundary}").as_bytes(), head_end) else {
            break;
        };
        let name = head
            .split("name=\"")
            .nth(1)
            .map(|n| n.split('"').next().unwrap().to_owned());
        out.push((name.unwrap_or_default(), body[head_end + 4..end].to_vec()));
        at = end + 2;
    }
    out
}

#[test]
fn http_and_stream_answer_the_sensor_maps() {
    crate::common::skip_unless_shared!("data/real-rgbd");
    let server = common::Server::start(&["--workers", "1"]);
    let (depth, camera) = tum();
    let depth = std::fs::read(depth).unwrap();
    // The service takes only the camera keys it knows: the shared file's intrinsics, its
    // depth scale and its free-text sensor description (no noise model).
    let file: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(camera).unwrap()).unwrap();
    let keys = ["fx", "fy", "cx", "cy", "depth_scale", "sensor"];
    let camera = serde_json::Value::Object(
        keys.iter()
            .map(|k| ((*k).to_owned(), file[*k].clone()))
            .collect(),
    )
    .to_string();
    common::rt().block_on(async {
        let post = |query: &str| {
            let form = reqwest::multipart::Form::new()
                .part("depth", reqwest::multipart::Part::bytes(depth.clone()))
                .part("camera", reqwest::multipart::Part::text(camera.clone()));
            reqwest::Client::new()
                .post(format!("{}/v1/roughness?{query}", server.url()))
                .multipart(form)
                .send()
        };
        let resp = post("mode=geometric&outputs=uncertainty,traversal")
            .await
            .unwrap();
        assert_eq!(resp.status().as_u16(), 422);
        let body = resp.text().await.unwrap();
        assert!(
            body.contains("bad_camera") && body.contains("kinect_v1") && body.contains("freiburg2"),
            "{body}"
        );
        let resp = post("mode=geometric&sensor=kinect_v1&outputs=uncertainty,traversal")
            .await
            .unwrap();
        assert_eq!(resp.status().as_u16(), 200);
        let ct = resp.headers()["content-type"].to_str().unwrap().to_owned();
        let parts = parts(&ct, &resp.bytes().await.unwrap());
        let names: Vec<&str> = parts.iter().map(|(n, _)| n.as_str()).collect();
        assert_eq!(names, ["roughness", "uncertainty", "traversal"]);
        let (w, h, _) = common::png16_values(&parts[1].1);
        assert_eq!((w, h), (640, 480));
        // The geometric mode served over HTTP is the terrain estimate under the sensor asked
        // for: the same 16-bit map as the pipeline in process (drops included).
        let (_, _, served) = common::png16_values(&parts[0].1);
        assert_eq!(
            served,
            terrain_png16(),
            "HTTP geometric map differs from the pipeline's"
        );
        let c = traversal_values(&parts[2].1);
        assert!(c.iter().all(|&n| n > 1000), "{c:?}");
        let resp = post("mode=geometric&sensor=kinect&outputs=traversal")
            .await
            .unwrap();
        assert_eq!(resp.status().as_u16(), 400);
        assert!(resp.text().await.unwrap().contains("sensor"));
        stream(&server, &depth).await;
    });
}

/// Over the stream: a Hello whose camera names the sensor and asks for the maps.
async fn stream(server: &common::Server, depth: &[u8]) {
    use futures_util::{SinkExt, StreamExt};
    use prost::Message as _;
    use tokio_tungstenite::tungstenite::Message;
    use tre::proto::v1 as pb;
    let url = format!("ws://{}/v1/stream", server.addr);
    let mut ws = tokio_tungstenite::connect_async(url).await.unwrap().0;
    let hello = kinect_hello();
    let frame = pb::Frame {
        sequence: 1,
        depth: depth.to_vec(),
        ..Default::default()
    };
    for msg in [
        pb::client_message::Msg::Hello(hello),
        pb::client_message::Msg::Frame(frame),
    ] {
        let bytes = pb::ClientMessage { msg: Some(msg) }.encode_to_vec();
        ws.send(Message::Binary(bytes.into())).await.unwrap();
    }
    loop {
        let Message::Binary(b) = ws.next().await.unwrap().unwrap() else {
            continue;
        };
        match pb::ServerMessage::decode(&b[..]).unwrap().msg.unwrap() {
            pb::server_message::Msg::Ready(_) => continue,
            pb::server_message::Msg::Result(r) => {
                let n = (r.width * r.height) as usize;
                assert_eq!((r.traversal.len(), r.uncertainty.len()), (n, 4 * n));
                // The stream's geometric map is the pipeline's too.
                let (_, _, served) = common::png16_values(&r.roughness);
                assert_eq!(
                    served,
                    terrain_png16(),
                    "stream geometric map differs from the pipeline's"
                );
                assert!(r.traversal.iter().all(|&t| t <= 2));
                assert!(
                    r.traversal.contains(&0)
                        && r.traversal.contains(&1)
                        && r.traversal.contains(&2)
                );
                return;
            }
            other => panic!("expected a Result, got {other:?}"),
        }
    }
}

/// A geometric-mode Hello whose camera (the TUM frame's) names the Kinect v1 and asks for the
/// traversal and uncertainty maps.
fn kinect_hello() -> tre::proto::v1::Hello {
    use tre::proto::v1 as pb;
    pb::Hello {
        camera: Some(pb::Camera {
            fx: 520.9,
            fy: 521.0,
            cx: 325.1,
            cy: 249.7,
            depth_scale: Some(5000.0),
            sensor: Some("kinect_v1".into()),
            ..Default::default()
        }),
        mode: pb::Mode::Geometric as i32,
        want_traversal: true,
        want_uncertainty: true,
        ..Default::default()
    }
}
