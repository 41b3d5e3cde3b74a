//! The choices a [`ServeConfig`] leaves to the service (workers, threads, queue, models folder)
//! and its checks, run by [`serve`](crate::serve) before anything starts, so that a library user
//! gets the same settings and refusals as `tre serve`.

use std::path::Path;

use crate::{ServeConfig, ServeError};
use tre_model::{
    check_threads, Batching, BatchingError, ExecutionProvider, ProviderMissing, SessionConfig,
    ThreadsError,
};

/// Shortest API key accepted.
pub const MIN_API_KEY_CHARS: usize = 16;

/// A setting that the service refuses.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum ConfigError {
    /// A limit or timeout of 0, which would refuse every request or close every connection.
    #[error("{flag} (ServeConfig::{field}) must be positive")]
    NotPositive {
        /// The `tre serve` option.
        flag: &'static str,
        /// The field of [`ServeConfig`].
        field: &'static str,
    },
    /// An API key too short to be one.
    #[error(
        "--api-key: {chars} characters is too short to be a key; use at least \
         {MIN_API_KEY_CHARS} (e.g. `openssl rand -hex 32`)"
    )]
    ApiKeyTooShort {
        /// Its length.
        chars: usize,
    },
    /// Workers or ONNX Runtime threads the cores cannot use.
    #[error(transparent)]
    Threads(#[from] ThreadsError),
    /// An execution provider this build lacks.
    #[error(transparent)]
    Provider(#[from] ProviderMissing),
    /// Batching bounds out of range.
    #[error("--batch-max / --batch-delay-ms (ServeConfig::batch_max, batch_delay): {0}")]
    Batching(#[from] BatchingError),
    /// No worker, or no room in the queue.
    #[error("{flag} (ServeConfig::{field}) must be at least 1 once chosen")]
    Empty {
        /// The `tre serve` option.
        flag: &'static str,
        /// The field of [`ServeConfig`].
        field: &'static str,
    },
}

impl ServeConfig {
    /// These settings with every choice they leave made for `cores` cores, then checked
    /// ([`validate`](Self::validate)): workers (0: one per core), ONNX Runtime threads per worker
    /// (0: cores / workers, at least 1), the queue (0: 2 per worker), the models folder
    /// ([`tre_model::find_models`]: the one given, else the usual places; logged), and an empty
    /// API key read as none. `tre serve` resolves its options before it starts; [`serve`](crate::serve)
    /// resolves settings that still leave a choice.
    ///
    /// # Errors
    ///
    /// [`ServeError::Manifest`] when no models folder is found, [`ServeError::Settings`] when
    /// [`validate`](Self::validate) refuses the result.
    pub fn resolve(mut self, cores: usize) -> Result<Self, ServeError> {
        if self.workers == 0 {
            self.workers = cores;
        }
        if self.ort_threads == 0 {
            self.ort_threads = (cores / self.workers.max(1)).max(1);
        }
        if self.queue == 0 {
            self.queue = 2 * self.workers;
        }
        self.models = Some(tre_model::find_models(self.models.as_deref())?);
        self.api_key = self.api_key.filter(|k| !k.is_empty());
        self.validate(cores)?;
        Ok(self)
    }

    /// Whether [`resolve`](Self::resolve) has nothing left to choose.
    pub fn is_resolved(&self) -> bool {
        self.models.is_some() && self.workers > 0 && self.ort_threads > 0 && self.queue > 0
    }

    /// The models folder (`models` until resolved).
    pub fn models_dir(&self) -> &Path {
        self.models.as_deref().unwrap_or(Path::new("models"))
    }

    /// The ONNX Runtime settings of each worker.
    ///
    /// # Errors
    ///
    /// [`ConfigError::Provider`] for a provider this build lacks.
    pub fn session(&self) -> Result<SessionConfig, ConfigError> {
        Ok(SessionConfig {
            intra_threads: self.ort_threads,
            provider: ExecutionProvider::of(self.provider, self.device_id)?,
            ..SessionConfig::default()
        })
    }

    /// The dynamic batching of these settings.
    pub fn batching(&self) -> Batching {
        Batching {
            max_batch: self.batch_max,
            max_delay: self.batch_delay,
        }
    }

    /// Refuses settings the service cannot run with: a limit or timeout of 0, an API key
    /// shorter than [`MIN_API_KEY_CHARS`], more workers or ONNX Runtime threads than `cores`
    /// can use (see [`check_threads`]), an execution provider this build lacks.
    pub fn validate(&self, cores: usize) -> Result<(), ConfigError> {
        self.session()?;
        self.batching().check()?;
        if let Some(&(flag, field, _)) = self.positive().iter().find(|(_, _, v)| *v == 0) {
            return Err(ConfigError::NotPositive { flag, field });
        }
        for (flag, field, n) in [
            ("--workers", "workers", self.workers),
            ("--queue", "queue", self.queue),
        ] {
            if n == 0 {
                return Err(ConfigError::Empty { flag, field });
            }
        }
        if let Some(key) = self
            .api_key
            .as_deref()
            .filter(|k| k.len() < MIN_API_KEY_CHARS)
        {
            return Err(ConfigError::ApiKeyTooShort { chars: key.len() });
        }
        check_threads(Some(self.workers), self.ort_threads, cores)?;
        Ok(())
    }

    /// The limits and timeouts that must be positive: option, field, value (timeouts in
    /// milliseconds).
    fn positive(&self) -> [(&'static str, &'static str, u128); 13] {
        let n = |v: usize| v as u128;
        [
            ("--max-body-bytes", "max_body_bytes", n(self.max_body_bytes)),
            ("--max-pixels", "max_pixels", n(self.max_pixels)),
            ("--max-side", "max_side", n(self.max_side)),
            ("--max-aspect", "max_aspect", n(self.max_aspect)),
            ("--max-concurrent", "max_concurrent", n(self.max_concurrent)),
            (
                "--header-timeout-ms",
                "header_timeout",
                self.header_timeout.as_millis(),
            ),
            (
                "--body-timeout-ms",
                "body_timeout",
                self.body_timeout.as_millis(),
            ),
            (
                "--request-timeout-ms",
                "request_timeout",
                self.request_timeout.as_millis(),
            ),
            (
                "--ws-max-message-bytes",
                "ws_max_message_bytes",
                n(self.ws_max_message_bytes),
            ),
            ("--max-streams", "max_streams", n(self.max_streams)),
            (
                "--ws-idle-timeout-ms",
                "ws_idle_timeout",
                self.ws_idle_timeout.as_millis(),
            ),
            (
                "--stall-timeout-ms",
                "stall_timeout",
                self.stall_timeout.as_millis(),
            ),
            (
                "--max-connections",
                "max_connections",
                n(self.max_connections),
            ),
        ]
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::time::Duration;

    #[test]
    fn the_defaults_pass_and_each_zero_names_its_option() {
        let chosen = ServeConfig {
            workers: 1,
            queue: 2,
            ..ServeConfig::default()
        };
        chosen.validate(2).unwrap();
        type Case = (fn(&mut ServeConfig), &'static str);
        let cases: [Case; 4] = [
            (|c| c.max_connections = 0, "--max-connections"),
            (|c| c.stall_timeout = Duration::ZERO, "--stall-timeout-ms"),
            (|c| c.max_body_bytes = 0, "--max-body-bytes"),
            (
                |c| c.ws_idle_timeout = Duration::ZERO,
                "--ws-idle-timeout-ms",
            ),
        ];
        for (set, flag) in cases {
            let mut cfg = ServeConfig {
                workers: 1,
                queue: 2,
                ..ServeConfig::default()
            };
            set(&mut cfg);
            let e = cfg.validate(2).unwrap_err().to_string();
            assert!(e.contains(flag) && e.contains("must be positive"), "{e}");
        }
    }

    #[test]
    fn short_keys_and_too_many_workers_are_refused() {
        let short = ServeConfig {
            api_key: Some("abc".into()),
            workers: 1,
            queue: 2,
            ..ServeConfig::default()
        };
        assert_eq!(
            short.validate(2),
            Err(ConfigError::ApiKeyTooShort { chars: 3 })
        );
        let many = ServeConfig {
            workers: 9,
            queue: 18,
            ..ServeConfig::default()
        };
        let e = many.validate(2).unwrap_err().to_string();
        assert!(e.contains("--workers 9: at most 8"), "{e}");
        for (batch_max, ms, says) in [
            (0, 2, "batch size 0"),
            (65, 2, "batch size 65"),
            (8, 1001, "batch delay"),
        ] {
            let cfg = ServeConfig {
                workers: 1,
                queue: 2,
                batch_max,
                batch_delay: Duration::from_millis(ms),
                ..ServeConfig::default()
            };
            let e = cfg.validate(2).unwrap_err().to_string();
            assert!(e.contains("--batch-max") && e.contains(says), "{e}");
        }
    }

    #[test]
    fn zeros_are_chosen_for_the_cores() {
        let dir = tempfile::tempdir().unwrap();
        std::fs::write(dir.path().join("manifest.json"), b"{}").unwrap();
        let cfg = ServeConfig {
            models: Some(dir.path().to_path_buf()),
            api_key: Some(String::new()),
            ..ServeConfig::default()
        };
        assert!(!cfg.is_resolved());
        let cfg = cfg.resolve(4).unwrap();
        assert_eq!((cfg.workers, cfg.ort_threads, cfg.queue), (4, 1, 8));
        assert_eq!(cfg.api_key, None);
        assert!(cfg.is_resolved());
        let two = ServeConfig {
            workers: 2,
            ..cfg.clone()
        };
        assert_eq!(two.resolve(4).unwrap().ort_threads, 1);
    }
}

/// The options of `tre serve` (the `cli` feature) become these settings.
#[cfg(all(test, feature = "cli"))]
mod cli_tests {
    use std::time::Duration;

    use clap::Parser;

    use crate::ServeConfig;

    #[derive(Debug, Parser)]
    struct Cli {
        #[command(flatten)]
        serve: ServeConfig,
    }

    fn parse(args: &[&str]) -> Result<ServeConfig, String> {
        let fixed = ["tre", "--workers", "1", "--queue", "2"];
        let cli = Cli::try_parse_from(fixed.iter().chain(args)).map_err(|e| e.to_string())?;
        cli.serve.validate(2).map_err(|e| e.to_string())?;
        Ok(cli.serve)
    }

    #[test]
    fn the_options_defaults_are_the_settings_defaults() {
        let cli = Cli::try_parse_from(["tre"]).unwrap();
        assert_eq!(cli.serve, ServeConfig::default());
    }

    #[test]
    fn the_connection_limits_are_set_and_zero_is_refused() {
        let cfg = parse(&[]).unwrap();
        assert_eq!(cfg.ws_idle_timeout, Duration::from_secs(60));
        assert_eq!(cfg.stall_timeout, Duration::from_secs(30));
        assert_eq!(cfg.request_timeout, Duration::from_secs(30));
        assert_eq!(cfg.max_connections, 1024);
        let cfg = parse(&[
            "--ws-idle-timeout-ms",
            "1500",
            "--stall-timeout-ms",
            "700",
            "--request-timeout-ms",
            "250",
            "--max-connections",
            "3",
        ])
        .unwrap();
        assert_eq!(cfg.ws_idle_timeout, Duration::from_millis(1500));
        assert_eq!(cfg.stall_timeout, Duration::from_millis(700));
        assert_eq!(cfg.request_timeout, Duration::from_millis(250));
        assert_eq!(cfg.max_connections, 3);
        for flag in [
            "--ws-idle-timeout-ms",
            "--stall-timeout-ms",
            "--request-timeout-ms",
            "--max-connections",
        ] {
            let e = parse(&[flag, "0"]).unwrap_err();
            assert!(e.contains("must be positive") && e.contains(flag), "{e}");
        }
    }
}
