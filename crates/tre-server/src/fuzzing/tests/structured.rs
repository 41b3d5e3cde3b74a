//! Inputs built field by field: camera objects with keys changed or removed, and Hellos and
//! frames with any values.

use std::sync::Arc;

use proptest::prelude::*;

use super::seeds::{camera_json, client_message, small_pngs};
use tre_proto::v1 as pb;

/// Any JSON value a camera key might be given.
fn json_value() -> impl Strategy<Value = serde_json::Value> {
    use serde_json::Value;
    prop_oneof![
        any::<f64>().prop_map(Value::from),
        prop_oneof![Just(0.0), Just(-1.0), Just(1e308), Just(500.0), Just(1e-9)]
            .prop_map(Value::from),
        any::<i64>().prop_map(Value::from),
        any::<u64>().prop_map(Value::from),
        ".{0,12}".prop_map(Value::from),
        any::<bool>().prop_map(Value::from),
        Just(Value::Null),
        prop::collection::vec(any::<f64>(), 0..4).prop_map(Value::from),
        Just(serde_json::json!({"sigma_mm": [1.0, 2.0]})),
    ]
}

/// A valid camera object with a few keys changed to any value (or unknown keys added) and a
/// few removed.
pub(super) fn camera_objects() -> impl Strategy<Value = Vec<u8>> {
    let keys = tre_io::CAMERA_KEYS.to_vec();
    let key = prop_oneof![
        8 => prop::sample::select(keys.clone()).prop_map(String::from),
        1 => "[a-z_]{1,10}",
    ];
    let changes = prop::collection::btree_map(key, json_value(), 0..4);
    let removals = prop::collection::vec(prop::sample::select(keys), 0..3);
    (changes, removals).prop_map(|(changes, removals)| {
        let serde_json::Value::Object(mut cam) =
            serde_json::from_slice(&camera_json()).expect("the seed camera is JSON; a bug")
        else {
            unreachable!("the seed camera is an object")
        };
        cam.extend(changes);
        for k in removals {
            cam.remove(k);
        }
        serde_json::to_vec(&cam).expect("a JSON value serialises; a bug")
    })
}

fn opt_f64() -> impl Strategy<Value = Option<f64>> {
    prop::option::of(prop_oneof![any::<f64>(), -200.0..200.0f64])
}

fn pb_cameras() -> impl Strategy<Value = Option<pb::Camera>> {
    let k = (
        any::<f64>(),
        0.0..2000.0f64,
        -100.0..1000.0f64,
        any::<f64>(),
    );
    let m = (opt_f64(), opt_f64(), opt_f64());
    let size = (prop::option::of(any::<u32>()), prop::option::of(0u32..100));
    let sensor = (
        prop::option::of("[a-z_0-9]{0,12}"),
        prop::collection::vec(any::<f64>(), 0..5),
    );
    prop::option::of((k, m, size, sensor).prop_map(
        |((fx, fy, cx, cy), (pitch_deg, height_m, depth_scale), (width, height), (name, sigma))| {
            pb::Camera {
                fx,
                fy,
                cx,
                cy,
                pitch_deg,
                height_m,
                depth_scale,
                width,
                height,
                sensor: name,
                sensor_sigma_mm: sigma,
            }
        },
    ))
}

/// Hellos and frames built field by field, with any values.
pub(super) fn stream_structured() -> impl Strategy<Value = Vec<u8>> {
    use pb::client_message::Msg;
    let hello = (
        pb_cameras(),
        (any::<i32>(), any::<i32>(), any::<i32>(), any::<u32>()),
        (opt_f64(), opt_f64(), opt_f64()),
        any::<(bool, bool, bool)>(),
    )
        .prop_map(
            |(camera, (mode, format, normals, dsac_hypotheses), (preview, r, s), (a, b, c))| {
                client_message(Msg::Hello(pb::Hello {
                    camera,
                    mode,
                    format,
                    seed: 3,
                    preview_max_m: preview,
                    want_traversable: a,
                    normals,
                    dsac_hypotheses,
                    max_roughness_cm: r,
                    max_slope_deg: s,
                    want_traversal: b,
                    want_uncertainty: c,
                    sensor: a.then(|| "kinect_v1".to_owned()),
                    sensor_sigma_mm: Vec::new(),
                    map: b.then(|| pb::MapSettings {
                        cell_m: 0.05,
                        side: 20,
                        send_hz: 0.0,
                        gravity: Vec::new(),
                    }),
                }))
            },
        );
    let images = Arc::new(small_pngs());
    let frame = (pb_cameras(), 0..3usize, 0..3usize).prop_map(move |(camera, i, d)| {
        let pick = |k: usize| match k {
            0 => Vec::new(),
            1 => images[0].clone(),
            _ => images[4].clone(),
        };
        client_message(Msg::Frame(pb::Frame {
            sequence: 9,
            timestamp_us: -1,
            image: pick(i),
            depth: pick(d),
            camera,
            pose: if i == 2 { vec![1.0; 16] } else { Vec::new() },
        }))
    });
    prop_oneof![hello, frame]
}
