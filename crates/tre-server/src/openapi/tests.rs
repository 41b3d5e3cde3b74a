//! The generated document against what the router serves, the query struct the handler reads,
//! and the checked-in copy.

use std::sync::Arc;

use axum::body::Body as HttpBody;
use axum::http::{Request, StatusCode};
use serde::de::{Deserialize, Deserializer, Visitor};
use tokio::sync::{watch, Semaphore};
use tower_service::Service;

use super::*;
use crate::metrics::Metrics;
use crate::query::RoughnessQuery;
use crate::refusals::RefusalLog;
use crate::workers::{PoolConfig, Workers};
use crate::{router, AppState, ServeConfig};
use tre_core::kinds::{names, names_of_these, MapFormat, Mode, NormalsMethod};

/// A service whose workers never start (there are no models): enough for every route to
/// answer, none with a map.
fn state() -> (Arc<AppState>, watch::Sender<bool>) {
    let cfg = ServeConfig {
        workers: 1,
        queue: 1,
        models: Some("no models here".into()),
        ..ServeConfig::default()
    };
    let metrics = Arc::new(Metrics::default());
    let pool = PoolConfig {
        workers: 1,
        queue: 1,
        models: cfg.models_dir().to_path_buf(),
        session: cfg.session().unwrap(),
        batching: cfg.batching(),
        limits: cfg.decode_limits(),
        defaults: cfg.defaults,
        calibration: None,
    };
    let workers = Workers::start(&pool, metrics.clone()).expect("a worker thread starts");
    let (stop, shutdown) = watch::channel(false);
    let state = AppState {
        concurrency: Arc::new(Semaphore::new(cfg.max_concurrent)),
        streams: Arc::new(Semaphore::new(cfg.max_streams)),
        waiting_streams: Arc::new(Semaphore::new(cfg.max_connections)),
        cfg,
        workers,
        metrics,
        manifest_json: "{}".into(),
        model_names: Vec::new(),
        shutdown,
        refusals: Arc::new(RefusalLog::default()),
        maps: crate::map::MapRegistry::default(),
    };
    (Arc::new(state), stop)
}

/// The status the router answers `method path` with (no body).
async fn status(app: &mut axum::Router, method: &str, path: &str) -> StatusCode {
    let req = Request::builder()
        .method(method)
        .uri(path)
        .body(HttpBody::empty())
        .expect("a request");
    std::future::poll_fn(|cx| Service::<Request<HttpBody>>::poll_ready(app, cx))
        .await
        .unwrap_or_else(|e| match e {});
    let resp = app.call(req).await.unwrap_or_else(|e| match e {});
    resp.status()
}

/// Every documented path answers its documented methods (not 404, not 405) and only those
/// (405 for the others); a path the document does not have is 404. The router is made from
/// the same handlers as the document ([`crate::routes`]), so a route outside it would have to be
/// added by hand: the documented paths are also listed here, as the service has them.
#[tokio::test]
async fn the_router_serves_what_the_document_lists_and_nothing_else() {
    let (state, _stop) = state();
    let mut app = router(state.clone());
    let doc = document();
    let paths = doc["paths"].as_object().expect("the document has paths");
    for (path, ops) in paths {
        for method in ["get", "post", "put", "delete", "patch"] {
            let got = status(&mut app, &method.to_uppercase(), path).await;
            // A path with a parameter names a resource: its handler's own 404 (no such stream)
            // is an answer, checked by its body below.
            if path.contains('{') && method == "get" && got == StatusCode::NOT_FOUND {
                continue;
            }
            if ops.get(method).is_some() {
                assert!(
                    got != StatusCode::NOT_FOUND && got != StatusCode::METHOD_NOT_ALLOWED,
                    "{method} {path}: {got}"
                );
            } else {
                assert_eq!(got, StatusCode::METHOD_NOT_ALLOWED, "{method} {path}");
            }
        }
    }
    let req = Request::builder()
        .uri("/v1/streams/none/map")
        .body(HttpBody::empty())
        .expect("a request");
    let resp = app.call(req).await.unwrap_or_else(|e| match e {});
    let body = axum::body::to_bytes(resp.into_body(), 1 << 16)
        .await
        .expect("a body");
    let text = String::from_utf8_lossy(&body);
    assert!(text.contains("no open stream"), "{text}");
    for path in ["/v1", "/v1/roughness/x", "/openapi.yaml", "/v2/roughness"] {
        assert_eq!(
            status(&mut app, "GET", path).await,
            StatusCode::NOT_FOUND,
            "{path}"
        );
    }
    let mut listed: Vec<&str> = paths.keys().map(String::as_str).collect();
    listed.sort_unstable();
    let served = [
        "/",
        "/healthz",
        "/metrics",
        "/openapi.json",
        "/readyz",
        "/v1/models",
        "/v1/roughness",
        "/v1/stream",
        "/v1/streams/{id}/map",
    ];
    assert_eq!(listed, served);
    state.workers.shutdown();
}

/// The field names a `Deserialize` struct reads (serde hands them to `deserialize_struct`).
fn serde_fields<T: for<'de> Deserialize<'de>>() -> &'static [&'static str] {
    #[derive(Debug)]
    struct Stop;
    impl std::fmt::Display for Stop {
        fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
            f.write_str("fields recorded")
        }
    }
    impl std::error::Error for Stop {}
    impl serde::de::Error for Stop {
        fn custom<M: std::fmt::Display>(_: M) -> Self {
            Stop
        }
    }
    struct Recorder<'a>(&'a mut &'static [&'static str]);
    impl<'de> Deserializer<'de> for Recorder<'_> {
        type Error = Stop;
        fn deserialize_any<V: Visitor<'de>>(self, _: V) -> Result<V::Value, Stop> {
            Err(Stop)
        }
        fn deserialize_struct<V: Visitor<'de>>(
            self,
            _: &'static str,
            fields: &'static [&'static str],
            _: V,
        ) -> Result<V::Value, Stop> {
            *self.0 = fields;
            Err(Stop)
        }
        serde::forward_to_deserialize_any! {
            bool i8 i16 i32 i64 i128 u8 u16 u32 u64 u128 f32 f64 char str string bytes byte_buf
            option unit unit_struct newtype_struct seq tuple tuple_struct map enum identifier
            ignored_any
        }
    }
    let mut fields: &'static [&'static str] = &[];
    assert!(T::deserialize(Recorder(&mut fields)).is_err());
    fields
}

/// The parameters of `POST /v1/roughness` are the fields of the query struct its handler
/// reads, in order, all optional query parameters; the choices list what their enums parse.
#[test]
fn the_roughness_parameters_are_the_handlers_query_struct() {
    let doc = document();
    let params = doc["paths"]["/v1/roughness"]["post"]["parameters"]
        .as_array()
        .expect("the roughness operation has parameters");
    let documented: Vec<&str> = params
        .iter()
        .map(|p| p["name"].as_str().expect("a parameter has a name"))
        .collect();
    let fields = serde_fields::<RoughnessQuery>();
    assert_eq!(documented, fields);
    assert_eq!(fields.len(), 17);
    for p in params {
        assert_eq!(
            (&p["in"], &p["required"]),
            (&"query".into(), &false.into()),
            "{p}"
        );
    }
    let choices = |name: &str| {
        let p = params.iter().find(|p| p["name"] == name).expect("listed");
        p["schema"]["enum"].clone()
    };
    assert_eq!(
        choices("format"),
        serde_json::json!(names_of_these(MapFormat::HTTP))
    );
    assert_eq!(
        choices("format"),
        serde_json::json!(["png16", "color", "colour", "npy"])
    );
    assert_eq!(choices("mode"), serde_json::json!(names::<Mode>()));
    assert_eq!(
        choices("normals"),
        serde_json::json!(names::<NormalsMethod>())
    );
}

/// The document is OpenAPI 3.0: no 3.1 construct is left.
#[test]
fn the_document_is_openapi_3_0() {
    fn walk(v: &Value, found: &mut Vec<String>) {
        match v {
            Value::Object(m) => {
                for (k, v) in m {
                    let exclusive = k.starts_with("exclusiveM") && !v.is_boolean();
                    if exclusive || (k == "type" && v.is_array()) {
                        found.push(format!("{k}: {v}"));
                    }
                    walk(v, found);
                }
            }
            Value::Array(a) => a.iter().for_each(|v| walk(v, found)),
            _ => {}
        }
    }
    let doc = document();
    assert_eq!(doc["openapi"], "3.0.3");
    let mut found = Vec::new();
    walk(&doc, &mut found);
    assert!(found.is_empty(), "3.1 constructs: {found:?}");
    let mut v = serde_json::json!({
        "openapi": "3.1.0",
        "a": {"type": ["number", "null"], "exclusiveMinimum": 0},
        "b": [{"type": ["string"], "exclusiveMaximum": 9.5}]
    });
    as_openapi_3_0(&mut v);
    let want = serde_json::json!({
        "openapi": "3.0.3",
        "a": {"type": "number", "nullable": true, "minimum": 0, "exclusiveMinimum": true},
        "b": [{"type": "string", "maximum": 9.5, "exclusiveMaximum": true}]
    });
    assert_eq!(v, want);
}

/// `docs/openapi.json` (the workspace's) is the generated document; `TRE_WRITE_OPENAPI=1`
/// rewrites it.
#[test]
fn the_checked_in_document_is_the_generated_one() {
    let path = concat!(env!("CARGO_MANIFEST_DIR"), "/../../docs/openapi.json");
    if std::env::var_os("TRE_WRITE_OPENAPI").is_some() {
        std::fs::write(path, document_json()).expect("writes docs/openapi.json");
    }
    let on_disk = std::fs::read_to_string(path).expect("reads docs/openapi.json");
    assert!(
        on_disk == document_json(),
        "docs/openapi.json is not the generated document; rewrite it with \
         TRE_WRITE_OPENAPI=1 cargo test -p tre-server --lib openapi"
    );
}
