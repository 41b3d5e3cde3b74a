//! TLS for the robot side (`wss://`, `https://`): one rustls configuration, with the ring
//! provider, trusting the Mozilla roots compiled in (webpki-roots) and, with `--ca-cert`, the
//! certificates of a private CA. `tre client` and `tre loadtest` share it, and so do their
//! HTTP (reqwest) and WebSocket (tokio-tungstenite) halves.

use std::path::Path;
use std::sync::Arc;

use rustls::pki_types::pem::PemObject;
use rustls::pki_types::CertificateDer;
use rustls::{ClientConfig, RootCertStore};

/// The client configuration: the public roots, plus every certificate in the PEM file
/// `ca_cert` when given. For why not, a message naming the file.
///
/// ```
/// let tls = tre_client::tls::client_config(None).unwrap();
/// assert_eq!(tls.alpn_protocols.len(), 0);
/// assert!(tre_client::tls::client_config(Some("no/such.pem".as_ref())).is_err());
/// ```
pub fn client_config(ca_cert: Option<&Path>) -> Result<Arc<ClientConfig>, String> {
    let mut roots = RootCertStore {
        roots: webpki_roots::TLS_SERVER_ROOTS.to_vec(),
    };
    if let Some(path) = ca_cert {
        let bad = |why: String| format!("--ca-cert {}: {why}", path.display());
        let certs = CertificateDer::pem_file_iter(path)
            .map_err(|e| bad(e.to_string()))?
            .collect::<Result<Vec<_>, _>>()
            .map_err(|e| bad(format!("not a PEM certificate file ({e})")))?;
        if certs.is_empty() {
            return Err(bad("holds no certificate".into()));
        }
        for cert in certs {
            roots
                .add(cert)
                .map_err(|e| bad(format!("not a usable CA certificate ({e})")))?;
        }
    }
    let provider = Arc::new(rustls::crypto::ring::default_provider());
    let config = ClientConfig::builder_with_provider(provider)
        .with_safe_default_protocol_versions()
        .map_err(|e| format!("TLS: {e}"))?
        .with_root_certificates(roots)
        .with_no_client_auth();
    Ok(Arc::new(config))
}
