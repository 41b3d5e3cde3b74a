//! The checks of a [`ServeConfig`], run by [`serve`](crate::serve) before anything starts, so
//! that a library user gets the same refusals as `tre serve`.

use crate::ServeConfig;
use tre_model::{check_threads, ThreadsError};

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
    /// Refuses settings the service cannot run with: a limit or timeout of 0, an API key
    /// shorter than [`MIN_API_KEY_CHARS`], more workers or ONNX Runtime threads than `cores`
    /// can use (see [`check_threads`]).
    pub fn validate(&self, cores: usize) -> Result<(), ConfigError> {
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
        check_threads(Some(self.workers), self.session.intra_threads, cores)?;
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
        ServeConfig::default().validate(2).unwrap();
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
    }
}
