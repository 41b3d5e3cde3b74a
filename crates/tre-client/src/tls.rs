//! TLS for the robot side (`wss://`, `https://`): one rustls configuration, with the ring
//! provider, trusting the Mozilla roots compiled in (webpki-roots) and, with `--ca-cert`, the
//! certificates of a private CA. `tre client` and `tre loadtest` share it, and so do their
//! HTTP (reqwest) and WebSocket (tokio-tungstenite) halves.

use std::path::{Path, PathBuf};
use std::sync::Arc;

use rustls::pki_types::pem::{self, PemObject};
use rustls::pki_types::CertificateDer;
use rustls::{ClientConfig, RootCertStore};

/// Why there is no TLS configuration.
// The cause is in the message, not a `source`: a report that prints the chain would say it
// twice.
#[derive(Debug, thiserror::Error)]
pub enum TlsError {
    /// The private CA's file cannot be used.
    #[error("--ca-cert {}: {reason}", path.display())]
    CaCert {
        /// The PEM file.
        path: PathBuf,
        /// What is wrong with it.
        reason: CaCertProblem,
    },
    /// rustls has no safe protocol version with its provider.
    #[error("TLS: {0}")]
    Protocols(rustls::Error),
}

/// What is wrong with a private CA's PEM file ([`TlsError::CaCert`]).
// The cause is in the message, not a `source` (as [`TlsError`]).
#[derive(Debug, thiserror::Error)]
pub enum CaCertProblem {
    /// The file cannot be opened.
    #[error("{0}")]
    Open(pem::Error),
    /// The file is not PEM, or a certificate in it does not decode.
    #[error("not a PEM certificate file ({0})")]
    NotPem(pem::Error),
    /// PEM without a certificate.
    #[error("holds no certificate")]
    Empty,
    /// A certificate rustls will not take as a root.
    #[error("not a usable CA certificate ({0})")]
    Unusable(rustls::Error),
}

/// The client configuration: the public roots, plus every certificate in the PEM file
/// `ca_cert` when given. For why not, an error naming the file.
///
/// ```
/// let tls = tre_client::tls::client_config(None).unwrap();
/// assert_eq!(tls.alpn_protocols.len(), 0);
/// let e = tre_client::tls::client_config(Some("no/such.pem".as_ref())).unwrap_err();
/// assert!(e.to_string().starts_with("--ca-cert no/such.pem: "), "{e}");
/// ```
pub fn client_config(ca_cert: Option<&Path>) -> Result<Arc<ClientConfig>, TlsError> {
    let mut roots = RootCertStore {
        roots: webpki_roots::TLS_SERVER_ROOTS.to_vec(),
    };
    if let Some(path) = ca_cert {
        let bad = |reason| TlsError::CaCert {
            path: path.to_owned(),
            reason,
        };
        let certs = CertificateDer::pem_file_iter(path)
            .map_err(|e| bad(CaCertProblem::Open(e)))?
            .collect::<Result<Vec<_>, _>>()
            .map_err(|e| bad(CaCertProblem::NotPem(e)))?;
        if certs.is_empty() {
            return Err(bad(CaCertProblem::Empty));
        }
        for cert in certs {
            roots
                .add(cert)
                .map_err(|e| bad(CaCertProblem::Unusable(e)))?;
        }
    }
    let provider = Arc::new(rustls::crypto::ring::default_provider());
    let config = ClientConfig::builder_with_provider(provider)
        .with_safe_default_protocol_versions()
        .map_err(TlsError::Protocols)?
        .with_root_certificates(roots)
        .with_no_client_auth();
    Ok(Arc::new(config))
}
