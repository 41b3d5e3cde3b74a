//! A stream that asks for a map: kitchen depth frames with their poses come back as Results and
//! MapUpdate messages whose layers grow with the frames; a non-rigid pose is a clear error and
//! the map keeps what it had; `GET /v1/streams/{id}/map` answers the same map.

use super::*;

/// The kitchen sequence, `../shared/data/real-rgbd-2/sevenscenes_redkitchen`.
const KITCHEN: &str = "data/real-rgbd-2/sevenscenes_redkitchen";

/// A kitchen sequence file (the test reading it checks first that [`KITCHEN`] is there).
fn kitchen(rel: &str) -> std::path::PathBuf {
    common::shared_root().join(KITCHEN).join(rel)
}

/// The 16 numbers of a pose file.
fn pose(i: u32) -> Vec<f64> {
    std::fs::read_to_string(kitchen(&format!("poses/frame-{i:06}.txt")))
        .unwrap()
        .split_whitespace()
        .map(|t| t.parse().unwrap())
        .collect()
}

/// A depth frame of the kitchen with its pose.
fn depth_frame(sequence: u64, i: u32, pose: Vec<f64>) -> Vec<u8> {
    pb::ClientMessage {
        msg: Some(pb::client_message::Msg::Frame(pb::Frame {
            sequence,
            depth: std::fs::read(kitchen(&format!("depth/frame-{i:06}.png"))).unwrap(),
            pose,
            ..Default::default()
        })),
    }
    .encode_to_vec()
}

/// The Result of a frame and the MapUpdate after it.
async fn result_and_map(ws: &mut Ws) -> (pb::Result, pb::MapUpdate) {
    let pb::server_message::Msg::Result(r) = next(ws).await else {
        panic!("expected a Result");
    };
    let pb::server_message::Msg::Map(m) = next(ws).await else {
        panic!("expected a MapUpdate");
    };
    (r, m)
}

/// A geometric Hello with the kitchen's camera and a map of 120 × 120 cells of 5 cm.
fn map_hello(gravity: Vec<f64>) -> Vec<u8> {
    pb::ClientMessage {
        msg: Some(pb::client_message::Msg::Hello(pb::Hello {
            mode: pb::Mode::Geometric as i32,
            camera: Some(pb::Camera {
                fx: 585.0,
                fy: 585.0,
                cx: 320.0,
                cy: 240.0,
                depth_scale: Some(1000.0),
                sensor: Some("kinect_v1".into()),
                ..Default::default()
            }),
            map: Some(pb::MapSettings {
                cell_m: 0.05,
                side: 120,
                send_hz: 0.0,
                gravity,
            }),
            ..Default::default()
        })),
    }
    .encode_to_vec()
}

#[test]
fn a_stream_keeps_a_map_of_its_posed_frames_and_serves_it_over_http() {
    common::skip_unless_shared!(KITCHEN);
    let server = Server::start(&["--workers", "1"]);
    let g: serde_json::Value =
        serde_json::from_slice(&std::fs::read(kitchen("gravity.json")).unwrap()).unwrap();
    let gravity: Vec<f64> = serde_json::from_value(g["gravity"].clone()).unwrap();
    rt().block_on(async {
        let mut ws = connect(&server).await;
        let hello = map_hello(gravity);
        send(&mut ws, hello).await;
        let pb::server_message::Msg::Ready(ready) = next(&mut ws).await else {
            panic!("expected Ready");
        };
        assert!(!ready.stream_id.is_empty());
        let mut seen = 0;
        for (n, i) in [0u32, 5, 10].into_iter().enumerate() {
            send(&mut ws, depth_frame(n as u64 + 1, i, pose(i))).await;
            let (r, m) = result_and_map(&mut ws).await;
            assert_eq!(
                (r.sequence, m.sequence, m.fused),
                (n as u64 + 1, n as u64 + 1, n as u64 + 1)
            );
            assert_eq!((m.side, m.layers.len()), (120, tre::map::LAYER_NAMES.len()));
            assert!((m.cell_m - 0.05).abs() < 1e-12);
            let count = &m.layers[2];
            assert_eq!(count.name, "count");
            assert_eq!(count.data.len(), 120 * 120 * 4);
            let cells = count
                .data
                .chunks_exact(4)
                .filter(|b| f32::from_le_bytes([b[0], b[1], b[2], b[3]]) > 0.0)
                .count();
            assert!(
                cells >= seen && cells > 500,
                "{cells} cells after frame {i}"
            );
            seen = cells;
        }
        // A pose that is not a rigid transform: an error for that frame; the map is unchanged.
        let mut bad = pose(15);
        bad[0] = 2.0;
        send(&mut ws, depth_frame(4, 15, bad)).await;
        let pb::server_message::Msg::Error(e) = next(&mut ws).await else {
            panic!("expected an Error");
        };
        assert_eq!((e.sequence, e.code.as_str()), (Some(4), "bad_request"));
        assert!(e.message.contains("frame.pose"), "{}", e.message);

        // The same map over HTTP while the stream is open.
        let (status, body) = get(server.addr, &format!("/v1/streams/{}/map", ready.stream_id));
        assert_eq!(status, 200);
        let m = pb::MapUpdate::decode(body.as_slice()).unwrap();
        assert_eq!(
            (m.fused, m.sequence, m.layers.len()),
            (3, 3, tre::map::LAYER_NAMES.len())
        );
        let (status, _) = get(server.addr, "/v1/streams/nonsense/map");
        assert_eq!(status, 404);
    });
}
