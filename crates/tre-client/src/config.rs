//! Settings of the streaming client: where the server is, what to ask it for, how fast to send
//! and how to reconnect, checked once by [`ClientConfig::validate`]. Those a user states are
//! options of `tre client` (clap's, behind the `cli` feature: each doc comment is its `--help`).

use std::time::Duration;

use super::error::{ConfigProblem, UrlProblem};
use super::ClientError;
use tre_core::kinds::{MapFormat, Mode, NormalsMethod, Traversability};
use tre_core::roughness::noise::SensorNoise;
use tre_io::CameraFile;

/// How fast frames go out.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Rate {
    /// At most this many frames per second: `send` waits for the next tick. Ticks keep their
    /// phase (a late frame does not delay the next ones; missed ticks are skipped, not sent in
    /// a burst). Frames sent while the connection is down are reported lost at once, so the
    /// robot keeps its cadence.
    Fixed(f64),
    /// One frame at a time: `send` waits until the previous frame has its answer (result,
    /// drop, error, timeout or loss) and the connection is up. Nothing is dropped by the server.
    AsFastAsResults,
}

/// The grid map a session asks the server to keep (docs/map.md).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MapRequest {
    /// Cell side, metres (1 mm to 1 m).
    pub cell_m: f64,
    /// Cells along each side of the square window (1 to 1,000).
    pub side: u32,
    /// The world's down direction in the poses' frame; `None`: from the first fused frame's
    /// gravity (its stated pitch, or its depth's ground plane).
    pub gravity: Option<[f64; 3]>,
}

impl Default for MapRequest {
    /// 4 cm cells, 200 a side (8 m), gravity from the first frame: as `tre map`.
    fn default() -> Self {
        Self {
            cell_m: 0.04,
            side: 200,
            gravity: None,
        }
    }
}

/// Exponential back-off between connection attempts: the first attempt is immediate, attempt
/// `k + 1` waits `initial · factor^(k−1)`, capped at `max`.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "cli", derive(clap::Args))]
pub struct Backoff {
    /// First wait between connection attempts, milliseconds (doubling, see --reconnect-factor).
    #[cfg_attr(feature = "cli", arg(long = "reconnect-initial-ms",
        value_name = "RECONNECT_INITIAL_MS", env = "TRE_CLIENT_RECONNECT_INITIAL_MS",
        default_value = "200", value_parser = tre_io::units::parse_millis))]
    pub initial: Duration,
    /// Longest wait between connection attempts, milliseconds.
    #[cfg_attr(feature = "cli", arg(long = "reconnect-max-ms", value_name = "RECONNECT_MAX_MS",
        env = "TRE_CLIENT_RECONNECT_MAX_MS", default_value = "5000",
        value_parser = tre_io::units::parse_millis))]
    pub max: Duration,
    /// Growth of the wait per failed attempt.
    #[cfg_attr(
        feature = "cli",
        arg(
            long = "reconnect-factor",
            value_name = "RECONNECT_FACTOR",
            env = "TRE_CLIENT_RECONNECT_FACTOR",
            default_value_t = 2.0
        )
    )]
    pub factor: f64,
    /// Failed connection attempts in a row before giving up (0: never).
    // The full path keeps clap from reading the option as optional: it always has a value,
    // and 0 is `None`.
    #[cfg_attr(feature = "cli", arg(long = "reconnect-attempts",
        value_name = "RECONNECT_ATTEMPTS", env = "TRE_CLIENT_RECONNECT_ATTEMPTS",
        default_value = "20", value_parser = attempts))]
    pub give_up_after: std::option::Option<u32>,
}

/// `--reconnect-attempts`: a count, 0 for never.
#[cfg(feature = "cli")]
fn attempts(text: &str) -> Result<Option<u32>, std::num::ParseIntError> {
    Ok(Some(text.parse()?).filter(|&n| n > 0))
}

impl Default for Backoff {
    fn default() -> Self {
        Self {
            initial: Duration::from_millis(200),
            max: Duration::from_secs(5),
            factor: 2.0,
            give_up_after: Some(20),
        }
    }
}

impl Backoff {
    /// The wait after `failed` failed attempts in a row (`failed ≥ 1`).
    ///
    /// ```
    /// use std::time::Duration;
    /// use tre_client::Backoff;
    /// let b = Backoff { initial: Duration::from_millis(100), max: Duration::from_secs(1), factor: 2.0, give_up_after: None };
    /// assert_eq!(b.delay(1), Duration::from_millis(100));
    /// assert_eq!(b.delay(3), Duration::from_millis(400));
    /// assert_eq!(b.delay(30), Duration::from_secs(1));
    /// ```
    pub fn delay(&self, failed: u32) -> Duration {
        let exp = i32::try_from(failed.saturating_sub(1)).unwrap_or(i32::MAX);
        let secs = self.initial.as_secs_f64() * self.factor.powi(exp);
        if secs.is_finite() && secs < self.max.as_secs_f64() {
            Duration::from_secs_f64(secs)
        } else {
            self.max
        }
    }

    /// Whether `failed` failed attempts in a row exhaust the allowance.
    pub fn exhausted(&self, failed: u32) -> bool {
        self.give_up_after.is_some_and(|n| failed >= n)
    }
}

/// Settings of a stream session.
#[derive(Debug, Clone, PartialEq)]
#[cfg_attr(feature = "cli", derive(clap::Args))]
pub struct ClientConfig {
    /// Server: ws://host:port/v1/stream, ws://host:port, http://host:port or host:port;
    /// wss:// or https:// for TLS (a TLS-terminating proxy in front of the service).
    #[cfg_attr(feature = "cli", arg(long, env = "TRE_SERVER"))]
    pub server: String,
    /// API key of a server started with --api-key (sent as `Authorization: Bearer KEY`).
    #[cfg_attr(
        feature = "cli",
        arg(long, env = "TRE_API_KEY", hide_env_values = true)
    )]
    pub api_key: Option<String>,
    /// PEM file of a private CA to trust beside the public roots, for a wss:// or https://
    /// server whose certificate it issued.
    #[cfg_attr(feature = "cli", arg(long, env = "TRE_CA_CERT"))]
    pub ca_cert: Option<std::path::PathBuf>,
    /// Intrinsics and mounting of the camera; `None`: the server's defaults (60° horizontal
    /// field of view, 60° pitch, 1 m height).
    #[cfg_attr(feature = "cli", arg(skip))]
    pub camera: Option<CameraFile>,
    /// Input mode; default: rgbd for frames with depth, else rgb.
    #[cfg_attr(feature = "cli", arg(long, env = "TRE_MODE", value_enum))]
    pub mode: Option<Mode>,
    /// Encoding of the maps asked of the server: png16 (SEQ_NAME.png, 16-bit, 0.1 mm per
    /// unit), color (a preview PNG) or f32 (SEQ_NAME.npy, float32 metres).
    #[cfg_attr(feature = "cli", arg(long, env = "TRE_CLIENT_FORMAT", default_value = "png16",
        value_parser = tre_core::kinds::value_parser_of(MapFormat::STREAM)))]
    pub format: MapFormat,
    /// Seed of the DSAC sampler: the same seed gives the same output.
    #[cfg_attr(feature = "cli", arg(long, env = "TRE_SEED", default_value_t = 0))]
    pub seed: u64,
    /// Initial normals: dsac (the paper's method) or ls (faster); default: the server's.
    #[cfg_attr(feature = "cli", arg(long, env = "TRE_CLIENT_NORMALS", value_enum))]
    pub normals: Option<NormalsMethod>,
    /// DSAC hypotheses per pixel, 1 to 64 (fewer are faster); default: the server's.
    #[cfg_attr(feature = "cli", arg(long, env = "TRE_CLIENT_DSAC_HYPOTHESES",
        value_parser = tre_core::kinds::dsac_hypotheses_parser()))]
    pub dsac_hypotheses: Option<u32>,
    /// Top of the colour scale of [`MapFormat::Color`], metres; `None`: 0.05.
    #[cfg_attr(feature = "cli", arg(skip))]
    pub preview_max_m: Option<f64>,
    /// Also ask for traversability, written as SEQ_NAME_traversable.png (255 = traversable).
    #[cfg_attr(
        feature = "cli",
        arg(long = "traversable", env = "TRE_CLIENT_TRAVERSABLE")
    )]
    pub want_traversable: bool,
    /// Also ask for the three-state map and the uncertainty (the camera must name a sensor
    /// noise model, docs/sensor-noise.md), written as SEQ_NAME_traversal.png (0 unknown,
    /// 1 traversable, 2 hazard) and SEQ_NAME_uncertainty.png (16-bit, 0.1 mm per unit).
    #[cfg_attr(feature = "cli", arg(long = "traversal", env = "TRE_CLIENT_TRAVERSAL"))]
    pub want_traversal: bool,
    /// Traversability: the largest roughness, centimetres (default 5).
    #[cfg_attr(feature = "cli", arg(long, env = "TRE_CLIENT_MAX_ROUGHNESS_CM"))]
    pub max_roughness_cm: Option<f64>,
    /// Traversability: the steepest slope, degrees (default 20).
    #[cfg_attr(feature = "cli", arg(long, env = "TRE_CLIENT_MAX_SLOPE_DEG"))]
    pub max_slope_deg: Option<f64>,
    /// Depth sensor noise model, overriding the camera JSON's "sensor" (as `tre infer
    /// --sensor`): a preset (kinect_v1, realsense_d435, azure_kinect, lidar, lidar_accumulated, passive_stereo, exact) or a,b,c.
    #[cfg_attr(feature = "cli", arg(long, env = "TRE_SENSOR"))]
    pub sensor: Option<SensorNoise>,
    /// Keep a grid map of the stream's frames on the server (their poses:
    /// [`super::Frame::pose`]) and send it after every answered frame
    /// ([`super::Event::Map`]); `None`: no map.
    #[cfg_attr(feature = "cli", arg(skip))]
    pub map: Option<MapRequest>,
    /// How fast frames go out.
    #[cfg_attr(feature = "cli", arg(skip = Rate::AsFastAsResults))]
    pub rate: Rate,
    /// Reconnection back-off (also used for the first connection).
    #[cfg_attr(feature = "cli", command(flatten))]
    pub reconnect: Backoff,
    /// A frame without an answer after this long is counted lost, milliseconds.
    #[cfg_attr(feature = "cli", arg(long = "frame-timeout-ms", value_name = "FRAME_TIMEOUT_MS",
        env = "TRE_CLIENT_FRAME_TIMEOUT_MS", default_value = "30000",
        value_parser = tre_io::units::parse_millis))]
    pub frame_timeout: Duration,
    /// Limit of each connection step (readiness check, WebSocket handshake, Hello → Ready).
    #[cfg_attr(feature = "cli", arg(skip = ClientConfig::default().connect_timeout))]
    pub connect_timeout: Duration,
    /// A connection on which nothing has been heard for this long is dropped and re-made (the
    /// server pings every 15 s).
    #[cfg_attr(feature = "cli", arg(skip = ClientConfig::default().silence_timeout))]
    pub silence_timeout: Duration,
    /// Before each connection, wait for `GET /readyz` to answer 200, so that frames do not
    /// meet a server still loading its models (a 404 counts as ready: a proxy without it).
    #[cfg_attr(feature = "cli", arg(skip = ClientConfig::default().wait_ready))]
    pub wait_ready: bool,
    /// Frames awaiting an answer that are remembered; beyond, the oldest is reported lost.
    #[cfg_attr(feature = "cli", arg(skip = ClientConfig::default().max_pending))]
    pub max_pending: usize,
    /// Events buffered for the application; when full, the connection stops reading.
    #[cfg_attr(feature = "cli", arg(skip = ClientConfig::default().event_capacity))]
    pub event_capacity: usize,
}

impl Default for ClientConfig {
    fn default() -> Self {
        Self {
            server: "ws://127.0.0.1:8080/v1/stream".to_owned(),
            api_key: None,
            ca_cert: None,
            camera: None,
            mode: None,
            format: MapFormat::Png16,
            seed: 0,
            normals: None,
            dsac_hypotheses: None,
            preview_max_m: None,
            want_traversable: false,
            want_traversal: false,
            max_roughness_cm: None,
            max_slope_deg: None,
            sensor: None,
            map: None,
            rate: Rate::AsFastAsResults,
            reconnect: Backoff::default(),
            frame_timeout: Duration::from_secs(30),
            connect_timeout: Duration::from_secs(10),
            silence_timeout: Duration::from_secs(45),
            wait_ready: true,
            max_pending: 256,
            event_capacity: 64,
        }
    }
}

/// The URLs a session talks to, derived from [`ClientConfig::server`].
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Endpoints {
    /// The WebSocket stream, `ws://host:port[/prefix]/v1/stream` (`wss://` with TLS).
    pub stream: String,
    /// The readiness probe, `http://host:port[/prefix]/readyz` (`https://` with TLS).
    pub readyz: String,
    /// Whether both go over TLS.
    pub tls: bool,
}

impl ClientConfig {
    /// Checks every setting; returns the URLs to use.
    pub fn validate(&self) -> Result<Endpoints, ClientError> {
        let bad = |field, reason| Err(ClientError::BadConfig { field, reason });
        if let Rate::Fixed(fps) = self.rate {
            if !(fps.is_finite() && fps > 0.0) {
                return bad("rate", ConfigProblem::Rate(fps));
            }
        }
        if let Err(reason) = Traversability::from_cm_deg(self.max_roughness_cm, self.max_slope_deg)
        {
            return bad("traversability", ConfigProblem::Traversability(reason));
        }
        let b = &self.reconnect;
        if b.initial.is_zero() || b.max < b.initial {
            return bad(
                "reconnect",
                ConfigProblem::BackoffRange {
                    initial: b.initial,
                    max: b.max,
                },
            );
        }
        if !(b.factor.is_finite() && b.factor >= 1.0) {
            return bad("reconnect.factor", ConfigProblem::BackoffFactor(b.factor));
        }
        if b.give_up_after == Some(0) {
            return bad("reconnect.give_up_after", ConfigProblem::NoAttempts);
        }
        for (field, d) in [
            ("frame_timeout", self.frame_timeout),
            ("connect_timeout", self.connect_timeout),
            ("silence_timeout", self.silence_timeout),
        ] {
            if d.is_zero() {
                return bad(field, ConfigProblem::ZeroDuration);
            }
        }
        if self.max_pending == 0 || self.event_capacity == 0 {
            return bad("max_pending / event_capacity", ConfigProblem::ZeroCount);
        }
        if let Some(m) = self.preview_max_m.filter(|m| !(m.is_finite() && *m > 0.0)) {
            return bad("preview_max_m", ConfigProblem::NotPositive(m));
        }
        if let Some(c) = &self.camera {
            if let Err(e) = c.intrinsics().and_then(|_| c.mounting()) {
                return bad("camera", ConfigProblem::Camera(e));
            }
        }
        if let Some(m) = &self.map {
            let gravity_ok = m
                .gravity
                .is_none_or(|g| g.iter().all(|v| v.is_finite()) && g.iter().any(|&v| v != 0.0));
            if !((0.001..=1.0).contains(&m.cell_m) && (1..=1000).contains(&m.side) && gravity_ok) {
                return bad("map", ConfigProblem::Map);
            }
        }
        endpoints(&self.server)
    }
}

/// The stream and readiness URLs for a server address (see [`ClientConfig::server`]).
///
/// ```
/// let e = tre_client::endpoints("http://10.0.0.2:8080").unwrap();
/// assert_eq!(e.stream, "ws://10.0.0.2:8080/v1/stream");
/// assert_eq!(e.readyz, "http://10.0.0.2:8080/readyz");
/// let e = tre_client::endpoints("ws://robot-gw/tre/v1/stream").unwrap();
/// assert_eq!(e.readyz, "http://robot-gw/tre/readyz");
/// let e = tre_client::endpoints("https://tre.example").unwrap();
/// assert_eq!(e.stream, "wss://tre.example/v1/stream");
/// assert_eq!(e.readyz, "https://tre.example/readyz");
/// ```
pub fn endpoints(server: &str) -> Result<Endpoints, ClientError> {
    let bad = |reason| ClientError::BadUrl {
        url: server.to_owned(),
        reason,
    };
    let s = server.trim();
    let (scheme, rest) = match s.split_once("://") {
        Some((scheme, rest)) => (scheme.to_ascii_lowercase(), rest),
        None => ("ws".to_owned(), s),
    };
    let tls = match scheme.as_str() {
        "ws" | "http" => false,
        "wss" | "https" => true,
        _ => return Err(bad(UrlProblem::Scheme(scheme))),
    };
    if rest.contains(['?', '#', ' ']) {
        return Err(bad(UrlProblem::QueryOrSpaces));
    }
    let (authority, path) = rest.find('/').map_or((rest, ""), |i| rest.split_at(i));
    if authority.is_empty() || authority.starts_with(':') {
        return Err(bad(UrlProblem::NoHost));
    }
    let path = path.trim_end_matches('/');
    let base = path.strip_suffix("/v1/stream").unwrap_or(path);
    let (ws, http) = if tls {
        ("wss", "https")
    } else {
        ("ws", "http")
    };
    Ok(Endpoints {
        stream: format!("{ws}://{authority}{base}/v1/stream"),
        readyz: format!("{http}://{authority}{base}/readyz"),
        tls,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn addresses_become_stream_and_readiness_urls() {
        for s in [
            "ws://127.0.0.1:8080/v1/stream",
            "ws://127.0.0.1:8080",
            "http://127.0.0.1:8080/",
            "127.0.0.1:8080",
            "WS://127.0.0.1:8080/v1/stream/",
        ] {
            let e = endpoints(s).unwrap();
            assert_eq!(e.stream, "ws://127.0.0.1:8080/v1/stream", "{s}");
            assert_eq!(e.readyz, "http://127.0.0.1:8080/readyz", "{s}");
            assert!(!e.tls);
        }
        for s in ["wss://h:8443/v1/stream", "https://h:8443", "WSS://h:8443/"] {
            let e = endpoints(s).unwrap();
            assert_eq!(e.stream, "wss://h:8443/v1/stream", "{s}");
            assert_eq!(e.readyz, "https://h:8443/readyz", "{s}");
            assert!(e.tls);
        }
        for (s, problem) in [
            ("FTP://h", UrlProblem::Scheme("ftp".into())),
            ("ws://", UrlProblem::NoHost),
            ("ws://h/?x=1", UrlProblem::QueryOrSpaces),
            (":80", UrlProblem::NoHost),
        ] {
            match endpoints(s) {
                Err(ClientError::BadUrl { url, reason }) => {
                    assert_eq!((url.as_str(), reason), (s, problem));
                }
                other => panic!("{s}: {other:?}"),
            }
        }
        assert_eq!(
            endpoints("ftp://h").unwrap_err().to_string(),
            "server address \"ftp://h\": the scheme must be ws://, wss://, http:// or https://"
        );
    }

    #[test]
    fn backoff_grows_to_its_cap_and_gives_up_when_told() {
        let b = Backoff {
            initial: Duration::from_millis(200),
            max: Duration::from_secs(5),
            factor: 2.0,
            give_up_after: Some(3),
        };
        let waits: Vec<u128> = (1..=7).map(|k| b.delay(k).as_millis()).collect();
        assert_eq!(waits, [200, 400, 800, 1600, 3200, 5000, 5000]);
        assert_eq!(b.delay(u32::MAX), Duration::from_secs(5));
        assert!(!b.exhausted(2) && b.exhausted(3));
        // The default gives up after 20 failed attempts in a row (`--reconnect-attempts`'s).
        assert!(!Backoff::default().exhausted(19) && Backoff::default().exhausted(20));
        let never = Backoff {
            give_up_after: None,
            ..b
        };
        assert!(!never.exhausted(u32::MAX));
    }

    #[test]
    fn nonsense_settings_name_the_field() {
        let field = |cfg: ClientConfig| match cfg.validate() {
            Err(ClientError::BadConfig { field, .. }) => field,
            other => panic!("expected BadConfig, got {other:?}"),
        };
        let base = ClientConfig::default();
        assert!(base.validate().is_ok());
        let rate = ClientConfig {
            rate: Rate::Fixed(0.0),
            ..base.clone()
        };
        assert_eq!(field(rate), "rate");
        let mut b = base.clone();
        b.reconnect.factor = 0.5;
        assert_eq!(field(b), "reconnect.factor");
        let t = ClientConfig {
            frame_timeout: Duration::ZERO,
            ..base.clone()
        };
        assert_eq!(field(t), "frame_timeout");
        let cam = ClientConfig {
            camera: Some(CameraFile {
                fx: -1.0,
                fy: 1.0,
                cx: 0.0,
                cy: 0.0,
                width: None,
                height: None,
                depth_scale: None,
                pitch_deg: None,
                height_m: None,
                sensor: None,
            }),
            ..base
        };
        assert_eq!(field(cam), "camera");
    }
}
