//! Tests of the headers of an answer against the OpenAPI document.

use super::*;

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
