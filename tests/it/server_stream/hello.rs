//! The hello's thresholds and DSAC hypotheses, results equal to `tre infer`, and the latest
//! frame winning with drops reported.

use super::*;

#[test]
fn the_hello_sets_the_traversability_thresholds() {
    crate::common::skip_unless_shared!("data/real-rgbd");
    let server = Server::start(&["--workers", "1"]);
    let image = std::fs::read(real("slambook2_ch7/2.png")).unwrap();
    rt().block_on(async {
        // (traversable pixels, pixels with roughness) under each pair of thresholds.
        let mut counts = Vec::new();
        for (sequence, (cm, deg)) in [
            (None, None),
            (Some(1e4), Some(90.0)),
            (Some(1e-4), Some(0.0)),
        ]
        .into_iter()
        .enumerate()
        {
            let hello = hello_with(cm, deg);
            counts.push(traversable_and_valid(&server, hello, sequence as u64 + 1, &image).await);
        }
        let (default, loose, strict) = (counts[0], counts[1], counts[2]);
        assert!(
            default.1 > 0 && default.1 == loose.1 && loose.1 == strict.1,
            "{counts:?}"
        );
        assert_eq!(
            loose.0, loose.1,
            "every pixel with roughness passes 100 m and 90°"
        );
        assert_eq!(strict.0, 0, "none passes 1 µm and 0°");
        assert!(0 < default.0 && default.0 < default.1, "{counts:?}");

        let mut ws = connect(&server).await;
        send(&mut ws, hello_with(None, Some(95.0))).await;
        match next(&mut ws).await {
            pb::server_message::Msg::Error(e) => {
                assert_eq!(e.code, "bad_request");
                assert!(e.message.contains("hello.max_slope_deg"), "{}", e.message);
            }
            other => panic!("expected an Error, got {other:?}"),
        }
    });
}

/// An RGB-mode Hello for float maps with the traversable map, under these thresholds, with
/// the TUM camera at a stated pitch (without one, `rgb`'s gravity is unknown and nothing is
/// traversable).
fn hello_with(max_roughness_cm: Option<f64>, max_slope_deg: Option<f64>) -> Vec<u8> {
    pb::ClientMessage {
        msg: Some(pb::client_message::Msg::Hello(pb::Hello {
            camera: Some(pb::Camera {
                fx: 520.9,
                fy: 521.0,
                cx: 325.1,
                cy: 249.7,
                pitch_deg: Some(30.0),
                height_m: Some(1.0),
                ..Default::default()
            }),
            mode: pb::Mode::Rgb as i32,
            format: pb::Format::F32 as i32,
            want_traversable: true,
            max_roughness_cm,
            max_slope_deg,
            ..Default::default()
        })),
    }
    .encode_to_vec()
}

/// On a new stream opened with `hello`, frame `sequence` of `image`: its traversable pixels and
/// its pixels with roughness.
async fn traversable_and_valid(
    server: &Server,
    hello: Vec<u8>,
    sequence: u64,
    image: &[u8],
) -> (usize, usize) {
    let mut ws = connect(server).await;
    send(&mut ws, hello).await;
    assert!(matches!(
        next(&mut ws).await,
        pb::server_message::Msg::Ready(_)
    ));
    send(&mut ws, frame(sequence, image.to_vec())).await;
    let pb::server_message::Msg::Result(r) = next(&mut ws).await else {
        panic!("expected a Result");
    };
    let valid = r
        .roughness
        .chunks_exact(4)
        .filter(|b| f32::from_le_bytes([b[0], b[1], b[2], b[3]]).is_finite())
        .count();
    let traversable = r.traversable.iter().filter(|&&t| t == 1).count();
    // The Result names what ran and where gravity came from; nothing was assumed.
    assert_eq!(r.mode, "rgb");
    assert!(r.assumed.is_empty(), "{:?}", r.assumed);
    assert!(
        r.gravity.starts_with("stated; pitch_deg=30.0"),
        "{}",
        r.gravity
    );
    ws.close(None).await.unwrap();
    (traversable, valid)
}

#[test]
fn the_hello_chooses_dsac_hypotheses_and_a_bad_number_is_an_error() {
    crate::common::skip_unless_shared!("data/real-rgbd");
    let server = Server::start(&["--workers", "1"]);
    let path = real("slambook2_ch7/2.png");
    let four = infer_png16(&[
        path.to_str().unwrap(),
        "--mode",
        "rgb",
        "--dsac-hypotheses",
        "4",
    ]);
    let hello_with = |dsac_hypotheses| {
        pb::ClientMessage {
            msg: Some(pb::client_message::Msg::Hello(pb::Hello {
                mode: pb::Mode::Rgb as i32,
                dsac_hypotheses,
                ..Default::default()
            })),
        }
        .encode_to_vec()
    };
    rt().block_on(async {
        let mut ws = connect(&server).await;
        send(&mut ws, hello_with(65)).await;
        match next(&mut ws).await {
            pb::server_message::Msg::Error(e) => {
                assert_eq!(e.code, "bad_request");
                assert!(e.message.contains("hello.dsac_hypotheses"), "{}", e.message);
                assert!(e.message.contains("1 to 64"), "{}", e.message);
            }
            other => panic!("expected an Error, got {other:?}"),
        }
        send(&mut ws, hello_with(4)).await;
        assert!(matches!(
            next(&mut ws).await,
            pb::server_message::Msg::Ready(_)
        ));
        send(&mut ws, frame(1, std::fs::read(&path).unwrap())).await;
        match next(&mut ws).await {
            pb::server_message::Msg::Result(r) => {
                assert_eq!(png16_values(&r.roughness), four, "K = 4 over the stream");
            }
            other => panic!("expected a Result, got {other:?}"),
        }
        ws.close(None).await.unwrap();
    });
}

#[test]
fn stream_results_equal_tre_infer() {
    crate::common::skip_unless_shared!("data/real-rgbd");
    let server = Server::start(&["--workers", "1"]);
    let path = real("slambook2_ch7/2.png");
    let reference = infer_png16(&[path.to_str().unwrap(), "--mode", "rgb"]);
    rt().block_on(async {
        let mut ws = connect(&server).await;
        handshake(&mut ws, pb::Format::Png16, pb::Mode::Rgb).await;
        let image = std::fs::read(&path).unwrap();
        for seq in [7u64, 8, 9] {
            send(&mut ws, frame(seq, image.clone())).await;
            match next(&mut ws).await {
                pb::server_message::Msg::Result(r) => {
                    assert_eq!(r.sequence, seq);
                    assert_eq!(r.timestamp_us, 1_000 + seq as i64);
                    assert_eq!((r.width, r.height), (640, 480));
                    assert_eq!(r.scale_m, 1e-4);
                    assert!(r.timings.iter().any(|t| t.stage == "normals" && t.ms > 0.0));
                    assert!(r.latency_ms > 0.0);
                    assert_eq!(png16_values(&r.roughness), reference, "frame {seq}");
                }
                other => panic!("expected a Result, got {other:?}"),
            }
        }
        ws.close(None).await.unwrap();
    });
}

#[test]
fn latest_frame_wins_and_drops_are_reported() {
    crate::common::skip_unless_shared!("data/real-rgbd");
    let server = Server::start(&["--workers", "1"]);
    let image = std::fs::read(real("slambook2_ch7/1.png")).unwrap();
    rt().block_on(async {
        let mut ws = connect(&server).await;
        handshake(&mut ws, pb::Format::F32, pb::Mode::Rgb).await;
        for seq in 0..6 {
            send(&mut ws, frame(seq, image.clone())).await;
        }
        let (mut results, mut dropped, mut last_total) = (Vec::new(), Vec::new(), 0);
        while results.len() + dropped.len() < 6 {
            match next(&mut ws).await {
                pb::server_message::Msg::Result(r) => {
                    assert_eq!(r.roughness.len(), 640 * 480 * 4);
                    last_total = last_total.max(r.dropped_total);
                    results.push(r.sequence);
                }
                pb::server_message::Msg::Dropped(d) => {
                    assert_eq!(d.dropped_total, dropped.len() as u64 + 1);
                    dropped.push(d.sequence);
                }
                other => panic!("unexpected {other:?}"),
            }
        }
        // Frames sent back to back while one runs: the first and the newest are processed, the
        // ones in between are dropped, each once, and no frame is lost without a word.
        assert_eq!(results.first(), Some(&0));
        assert_eq!(results.last(), Some(&5));
        assert!(!dropped.is_empty(), "nothing was dropped");
        let mut all: Vec<u64> = results.iter().chain(&dropped).copied().collect();
        all.sort_unstable();
        assert_eq!(all, (0..6).collect::<Vec<_>>());
        assert_eq!(last_total, dropped.len() as u64);
    });
    let metrics = String::from_utf8(get(server.addr, "/metrics").1).unwrap();
    assert!(!metrics.contains("tre_frames_dropped_total 0"));
}
