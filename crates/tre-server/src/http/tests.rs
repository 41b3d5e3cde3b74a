//! Tests of the body's pace, and of the headers of an answer against the OpenAPI document.

use super::*;
use std::time::Duration;

/// Within a window nothing is judged; at its end, too few bytes is a 408 naming the option,
/// enough starts the next window afresh (earlier bytes do not carry over).
#[test]
fn body_pace_judges_each_window() {
    let mut pace = BodyPace::new(1024);
    let t0 = pace.since;
    assert_eq!(pace.deadline(), Some(t0 + BODY_RATE_WINDOW));
    pace.check(10, t0 + Duration::from_secs(1)).unwrap();
    pace.check(6000, t0 + BODY_RATE_WINDOW).unwrap();
    assert_eq!((pace.since, pace.bytes), (t0 + BODY_RATE_WINDOW, 0));
    let e = pace.check(100, t0 + 2 * BODY_RATE_WINDOW).unwrap_err();
    assert_eq!(e.code(), ErrorCode::RequestTimeout);
    assert!(e.to_string().contains("--min-body-rate"), "{e}");
    assert!(e.to_string().contains("20 bytes/s"), "{e}");
    let mut off = BodyPace::new(0);
    assert_eq!(off.deadline(), None);
    off.check(0, t0 + Duration::from_secs(3600)).unwrap();
}

/// Every header an answer of `POST /v1/roughness` carries, the optional ones included (an
/// assumption, a warning), is declared on its 200 response.
#[test]
fn every_header_of_a_roughness_answer_is_declared() {
    use tre_core::kinds::{MapFormat, Mode};
    use tre_pipeline::{Assumption, Gravity, GravityUnknown};
    let reply = FrameReply {
        size: (4, 3),
        working_size: (4, 3),
        roughness: Vec::new(),
        format: MapFormat::Png16,
        extras: Vec::new(),
        traversable: Vec::new(),
        traversal: Vec::new(),
        uncertainty: Vec::new(),
        timings: tre_pipeline::StageTimings::default(),
        mode: Mode::Rgb,
        assumed: vec![Assumption::Intrinsics],
        gravity: Gravity::Unknown(GravityUnknown::NoDepth),
        warnings: vec!["a warning".to_owned()],
    };
    let sent = reply_headers(&reply);
    assert!(sent.contains_key("x-tre-assumed") && sent.contains_key("warning"));
    let doc = crate::openapi::document();
    let declared = doc
        .pointer("/paths/~1v1~1roughness/post/responses/200/headers")
        .and_then(serde_json::Value::as_object)
        .expect("the 200 answer declares headers");
    let declared: Vec<String> = declared.keys().map(|k| k.to_ascii_lowercase()).collect();
    for name in sent.keys() {
        assert!(
            declared.iter().any(|d| d == name.as_str()),
            "{name} is sent but not declared (declared: {declared:?})"
        );
    }
}
