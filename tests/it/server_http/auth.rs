//! `--api-key` and `--allow-origin` guard every route, the stream upgrade included.

use super::*;

/// With `--api-key`, every route but `/healthz` and `/readyz` wants the Bearer key (401
/// otherwise, with `WWW-Authenticate`), and foreign browser origins are refused (403) unless
/// on `--allow-origin`, whose preflights are answered and answers carry their allow-origin.
#[test]
fn the_api_key_and_the_origin_allow_list_guard_every_route() {
    crate::common::skip_unless_shared!("data/real-rgbd");
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
        preflights_are_answered_for_allowed_origins(&client, &url, ops).await;
        // The stream upgrade: no key 401, a foreign origin 403, the key 101.
        stream_upgrade_is_guarded(server.addr, &bearer).await;
    });
}

/// Preflights from `ops` (on `--allow-origin`) are answered with its allow-origin and the
/// authorization header allowed; one from another origin is refused.
async fn preflights_are_answered_for_allowed_origins(
    client: &reqwest::Client,
    url: &str,
    ops: &str,
) {
    let preflight = |origin: &'static str| {
        client
            .request(reqwest::Method::OPTIONS, url)
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
}

/// The stream upgrade with `--api-key`: no key 401, a foreign origin 403, the key 101.
async fn stream_upgrade_is_guarded(addr: std::net::SocketAddr, bearer: &str) {
    use tokio_tungstenite::tungstenite::client::IntoClientRequest;
    let ws_url = format!("ws://{addr}/v1/stream");
    for (auth, origin, status) in [
        (None, None, 401),
        (Some(bearer), Some("http://evil.example"), 403),
        (Some(bearer), None, 101),
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
}
