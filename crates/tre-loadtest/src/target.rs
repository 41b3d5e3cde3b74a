//! The service under test: its URL checked and resolved once, with the safety rule that a host
//! name must resolve to loopback unless remote targets are allowed.

use std::net::{IpAddr, SocketAddr};
use std::time::Duration;

use reqwest::Url;

use super::problems::UrlProblem;
use super::LoadError;

/// Time the start-up probe waits for a TCP connection.
const PROBE_TIMEOUT: Duration = Duration::from_secs(5);

/// A resolved service address.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Target {
    /// The host as written in the URL (sent as `Host`).
    pub host: String,
    /// The address connected to (resolved once, so the check and the load meet the same host).
    pub addr: SocketAddr,
    /// Base path without a trailing slash (`""` for the root).
    pub base_path: String,
    /// Whether the service is reached over TLS (`https://`, the stream over `wss://`).
    pub tls: bool,
}

/// What the host part of a URL is.
#[derive(Debug, Clone, PartialEq, Eq)]
pub(crate) enum HostKind {
    /// An IP address written out: the user chose it, loopback or not.
    Ip(IpAddr),
    /// A name to resolve: allowed only if every address is loopback, or with `allow_remote`.
    Name(String),
}

/// Splits `url` into its host, port, base path and whether it is over TLS; `http://`, `ws://`,
/// `https://` and `wss://` are accepted.
pub(crate) fn parse(url: &str) -> Result<(HostKind, u16, String, bool), LoadError> {
    let bad = |why: UrlProblem| LoadError::Url {
        url: url.into(),
        why,
    };
    let parsed = Url::parse(url).map_err(|e| bad(e.into()))?;
    let (default_port, tls) = match parsed.scheme() {
        "http" | "ws" => (80, false),
        "https" | "wss" => (443, true),
        _ => return Err(bad(UrlProblem::Scheme)),
    };
    if parsed.query().is_some() || parsed.fragment().is_some() {
        return Err(bad(UrlProblem::QueryOrFragment));
    }
    let host = match parsed.host_str() {
        None | Some("") => return Err(bad(UrlProblem::NoHost)),
        Some(h) => {
            let bare = h.trim_start_matches('[').trim_end_matches(']');
            bare.parse::<IpAddr>()
                .map_or_else(|_| HostKind::Name(h.to_owned()), HostKind::Ip)
        }
    };
    let port = parsed.port().unwrap_or(default_port);
    let base = parsed.path().trim_end_matches('/').to_owned();
    Ok((host, port, base, tls))
}

/// Whether every address in `addrs` is loopback.
pub(crate) fn all_loopback(addrs: &[SocketAddr]) -> bool {
    !addrs.is_empty() && addrs.iter().all(|a| a.ip().is_loopback())
}

/// The safety rule for a host name: every address it resolves to must be loopback, unless
/// `allow_remote`.
pub(crate) fn check_resolved(
    host: &str,
    addrs: &[SocketAddr],
    allow_remote: bool,
) -> Result<(), LoadError> {
    if allow_remote || all_loopback(addrs) {
        return Ok(());
    }
    Err(LoadError::Remote {
        host: host.into(),
        addrs: list(addrs),
    })
}

impl Target {
    /// Parses `url`, resolves its host and connects once to check that something listens.
    /// A host name that resolves to any non-loopback address is refused unless
    /// `allow_remote`; an IP address written in the URL is taken as given.
    pub async fn resolve(url: &str, allow_remote: bool) -> Result<Self, LoadError> {
        let (host, port, base_path, tls) = parse(url)?;
        let (host, addrs) = match host {
            HostKind::Ip(ip) => (ip_host(ip), vec![SocketAddr::new(ip, port)]),
            HostKind::Name(name) => {
                let addrs: Vec<SocketAddr> = tokio::net::lookup_host((name.as_str(), port))
                    .await
                    .map_err(|error| LoadError::Resolve {
                        host: name.clone(),
                        error,
                    })?
                    .collect();
                check_resolved(&name, &addrs, allow_remote)?;
                (name, addrs)
            }
        };
        let addr = first_listening(&addrs).await?;
        Ok(Self {
            host,
            addr,
            base_path,
            tls,
        })
    }

    /// A target at `addr` without probing it (tests, or a caller that checked it).
    pub fn at(addr: SocketAddr) -> Self {
        Self {
            host: ip_host(addr.ip()),
            addr,
            base_path: String::new(),
            tls: false,
        }
    }

    /// `Host` value with the port.
    pub fn authority(&self) -> String {
        format!("{}:{}", self.host, self.addr.port())
    }

    /// URL of `POST /v1/roughness`.
    pub fn roughness_url(&self) -> String {
        let scheme = if self.tls { "https" } else { "http" };
        format!(
            "{scheme}://{}{}/v1/roughness",
            self.authority(),
            self.base_path
        )
    }

    /// URL of the stream.
    pub fn stream_url(&self) -> String {
        let scheme = if self.tls { "wss" } else { "ws" };
        format!(
            "{scheme}://{}{}/v1/stream",
            self.authority(),
            self.base_path
        )
    }
}

/// An IP as a URL host (`[::1]` for IPv6).
fn ip_host(ip: IpAddr) -> String {
    match ip {
        IpAddr::V4(v4) => v4.to_string(),
        IpAddr::V6(v6) => format!("[{v6}]"),
    }
}

fn list(addrs: &[SocketAddr]) -> String {
    addrs
        .iter()
        .map(ToString::to_string)
        .collect::<Vec<_>>()
        .join(", ")
}

/// The first of `addrs` that accepts a TCP connection.
async fn first_listening(addrs: &[SocketAddr]) -> Result<SocketAddr, LoadError> {
    let mut last = std::io::Error::new(std::io::ErrorKind::NotFound, "no address");
    for &addr in addrs {
        match tokio::time::timeout(PROBE_TIMEOUT, tokio::net::TcpStream::connect(addr)).await {
            Ok(Ok(_)) => return Ok(addr),
            Ok(Err(e)) => last = e,
            Err(_) => last = std::io::Error::new(std::io::ErrorKind::TimedOut, "timed out"),
        }
    }
    Err(LoadError::Connect {
        addrs: list(addrs),
        error: last,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn urls_split_into_host_port_and_prefix() {
        let (h, p, b, tls) = parse("http://127.0.0.1:8080").expect("parses");
        assert_eq!(h, HostKind::Ip(IpAddr::from([127, 0, 0, 1])));
        assert_eq!((p, b.as_str(), tls), (8080, "", false));
        let (h, p, b, _) = parse("http://localhost/tre/").expect("parses");
        assert_eq!(h, HostKind::Name("localhost".into()));
        assert_eq!((p, b.as_str()), (80, "/tre"));
        let (h, _, _, _) = parse("ws://[::1]:9000").expect("parses");
        assert_eq!(h, HostKind::Ip("::1".parse().expect("ip")));
        let (_, p, _, tls) = parse("https://localhost").expect("parses");
        assert_eq!((p, tls), (443, true));
        assert!(parse("wss://localhost:8443").expect("parses").3);
        for bad in ["ftp://x", "127.0.0.1:80", "http://127.0.0.1/?a=1"] {
            assert!(parse(bad).is_err(), "{bad} should be refused");
        }
    }

    #[test]
    fn only_loopback_sets_pass_the_check() {
        let a = |s: &str| s.parse::<SocketAddr>().expect("addr");
        assert!(all_loopback(&[a("127.0.0.1:1"), a("[::1]:1")]));
        assert!(!all_loopback(&[a("127.0.0.1:1"), a("10.0.0.1:1")]));
        assert!(!all_loopback(&[]));
        let remote = [a("127.0.0.1:80"), a("203.0.113.7:80")];
        let e = check_resolved("robots.example", &remote, false).expect_err("refused");
        let msg = e.to_string();
        assert!(
            msg.contains("203.0.113.7:80") && msg.contains("--allow-remote"),
            "{msg}"
        );
        assert!(check_resolved("robots.example", &remote, true).is_ok());
        assert!(check_resolved("localhost", &[a("[::1]:80")], false).is_ok());
    }

    #[tokio::test]
    async fn a_name_resolving_to_loopback_is_accepted_and_a_dead_port_is_an_error() {
        let listener = tokio::net::TcpListener::bind("127.0.0.1:0")
            .await
            .expect("bind");
        let port = listener.local_addr().expect("addr").port();
        let t = Target::resolve(&format!("http://localhost:{port}"), false)
            .await
            .expect("localhost is loopback");
        assert!(t.addr.ip().is_loopback());
        assert_eq!(
            t.roughness_url(),
            format!("http://localhost:{port}/v1/roughness")
        );
        drop(listener);
        let e = Target::resolve(&format!("http://127.0.0.1:{port}"), false).await;
        assert!(matches!(e, Err(LoadError::Connect { .. })), "{e:?}");
    }
}
