//! wss:// and https:// through a TLS-terminating proxy with a private CA.

use super::*;

/// A CA and a certificate for `localhost` it issued, made here: (CA PEM, server chain, key).
fn test_pki() -> (
    String,
    Vec<rustls::pki_types::CertificateDer<'static>>,
    rustls::pki_types::PrivateKeyDer<'static>,
) {
    let ca_key = rcgen::KeyPair::generate().unwrap();
    let mut ca_params = rcgen::CertificateParams::new(Vec::<String>::new()).unwrap();
    ca_params.is_ca = rcgen::IsCa::Ca(rcgen::BasicConstraints::Unconstrained);
    ca_params
        .distinguished_name
        .push(rcgen::DnType::CommonName, "tre test CA");
    let ca = ca_params.self_signed(&ca_key).unwrap();
    let issuer = rcgen::Issuer::new(ca_params, ca_key);
    let key = rcgen::KeyPair::generate().unwrap();
    let leaf = rcgen::CertificateParams::new(vec!["localhost".to_owned()])
        .unwrap()
        .signed_by(&key, &issuer)
        .unwrap();
    let chain = vec![leaf.der().clone(), ca.der().clone()];
    let key = rustls::pki_types::PrivateKeyDer::Pkcs8(key.serialize_der().into());
    (ca.pem(), chain, key)
}

/// A TLS-terminating proxy on a loopback port in front of `upstream` (as Caddy or an Ingress
/// would be), on `rt`: TLS in, the plain bytes forwarded. Returns its address and the CA's PEM.
fn tls_proxy(rt: &tokio::runtime::Runtime, upstream: SocketAddr) -> (SocketAddr, String) {
    let (ca_pem, chain, key) = test_pki();
    let provider = std::sync::Arc::new(rustls::crypto::ring::default_provider());
    let config = rustls::ServerConfig::builder_with_provider(provider)
        .with_safe_default_protocol_versions()
        .unwrap()
        .with_no_client_auth()
        .with_single_cert(chain, key)
        .unwrap();
    let acceptor = tokio_rustls::TlsAcceptor::from(std::sync::Arc::new(config));
    let listener = rt
        .block_on(tokio::net::TcpListener::bind("127.0.0.1:0"))
        .unwrap();
    let addr = listener.local_addr().unwrap();
    rt.spawn(async move {
        while let Ok((tcp, _)) = listener.accept().await {
            let acceptor = acceptor.clone();
            tokio::spawn(async move {
                let Ok(mut tls) = acceptor.accept(tcp).await else {
                    return;
                };
                let Ok(mut plain) = tokio::net::TcpStream::connect(upstream).await else {
                    return;
                };
                let _ = tokio::io::copy_bidirectional(&mut tls, &mut plain).await;
            });
        }
    });
    (addr, ca_pem)
}

/// `tre client` and `tre loadtest` over TLS: through a TLS-terminating proxy in front of a
/// `tre serve` with an API key, with the proxy's private CA given by `--ca-cert`, the stream
/// (`wss://`) and HTTP (`https://`) both work and carry the key; without the CA the
/// certificate is refused and the error says so.
#[test]
fn the_client_and_the_load_tester_speak_tls_to_a_proxy_with_a_private_ca() {
    crate::common::skip_unless_shared!("data/real-rgbd");
    let key = "tls-test-key-0123456789";
    let (_serial, dir, server) = serve(&["--api-key", key]);
    let frames = make_frames(&dir.path().join("frames"));
    server.wait_ready();
    let rt = rt();
    let (proxy, ca_pem) = tls_proxy(&rt, server.addr);
    let ca = dir.path().join("ca.pem");
    std::fs::write(&ca, ca_pem).unwrap();
    let tre = |args: &[&str]| tre_with_key(key, args);
    let wss = format!("wss://localhost:{}/v1/stream", proxy.port());
    let out = dir.path().join("out");
    let frames_dir = dir.path().join("frames");
    let client = |extra: &[&str]| {
        let mut args = vec!["client", "--server", &wss, "--frames"];
        args.push(frames_dir.to_str().unwrap());
        args.extend(["--mode", "rgb", "--normals", "ls", "--limit", "2", "--out"]);
        args.push(out.to_str().unwrap());
        args.extend(extra);
        tre(&args)
    };
    let run = client(&["--ca-cert", ca.to_str().unwrap()]);
    assert!(
        run.status.success(),
        "{}",
        String::from_utf8_lossy(&run.stderr)
    );
    let csv = std::fs::read_to_string(out.join("frames.csv")).unwrap();
    assert_eq!(
        csv.lines().filter(|l| l.ends_with(",ok")).count(),
        2,
        "{csv}"
    );

    // Without the private CA: refused on the certificate, named, without retrying for long.
    let run = client(&["--reconnect-attempts", "1"]);
    let stderr = String::from_utf8_lossy(&run.stderr);
    assert!(!run.status.success());
    assert!(
        stderr.contains("certificate") || stderr.contains("UnknownIssuer"),
        "{stderr}"
    );

    // The load tester, over https:// and over the stream (wss://).
    loadtest_over_tls(dir.path(), proxy, &ca, &frames[0].1, key);
}

/// `tre ARGS` with `TRE_API_KEY` set to `key`.
fn tre_with_key(key: &str, args: &[&str]) -> std::process::Output {
    Command::new(env!("CARGO_BIN_EXE_tre"))
        .args(args)
        .env("TRE_API_KEY", key)
        .output()
        .unwrap()
}

/// `tre loadtest` through the proxy with its CA, over https:// and over the stream (wss://):
/// every request of each is answered.
fn loadtest_over_tls(dir: &Path, proxy: SocketAddr, ca: &Path, frame: &Path, key: &str) {
    let tre = |args: &[&str]| tre_with_key(key, args);
    let https = format!("https://localhost:{}", proxy.port());
    let frame = frame.to_str().unwrap();
    for protocol in ["http", "ws"] {
        let json = dir.join(format!("load-{protocol}.json"));
        let run = tre(&[
            "loadtest",
            "--url",
            &https,
            "--ca-cert",
            ca.to_str().unwrap(),
            "--protocol",
            protocol,
            "--requests",
            "3",
            "--frame",
            frame,
            "--json",
            json.to_str().unwrap(),
        ]);
        assert!(
            run.status.success(),
            "{protocol}: {}{}",
            String::from_utf8_lossy(&run.stdout),
            String::from_utf8_lossy(&run.stderr)
        );
        let report: serde_json::Value =
            serde_json::from_slice(&std::fs::read(&json).unwrap()).unwrap();
        assert_eq!(report["ok"], 3, "{protocol}: {report}");
    }
}
