//! Logging of bad input, rate-limited: the first problem of a kind is logged at once, then at
//! most one line per kind every [`Limiter::every`] with how many were skipped meanwhile; when
//! frames are good again, one line says so.

use std::collections::BTreeMap;
use std::time::{Duration, Instant};

/// Per kind: when it was last logged and how many since.
#[derive(Debug)]
pub(crate) struct Limiter {
    every: Duration,
    kinds: BTreeMap<&'static str, (Instant, u64)>,
    failing: bool,
}

impl Limiter {
    pub(crate) fn new(every: Duration) -> Self {
        Self {
            every,
            kinds: BTreeMap::new(),
            failing: false,
        }
    }

    /// A frame skipped for `kind`; `message` is logged when the kind is due. Returns whether a
    /// line was logged.
    pub(crate) fn skipped(&mut self, kind: &'static str, message: &str) -> bool {
        self.failing = true;
        let now = Instant::now();
        match self.kinds.get_mut(kind) {
            Some((last, count)) if now.duration_since(*last) < self.every => {
                *count += 1;
                false
            }
            Some((last, count)) => {
                tracing::warn!(
                    kind,
                    skipped_since = *count,
                    "frame skipped: {message} ({} more of this kind since the last line)",
                    *count
                );
                *last = now;
                *count = 0;
                true
            }
            None => {
                tracing::warn!(kind, "frame skipped: {message}");
                self.kinds.insert(kind, (now, 0));
                true
            }
        }
    }

    /// A frame processed: after skips, one line says the input recovered.
    pub(crate) fn good(&mut self) {
        if self.failing {
            tracing::info!("frames are good again");
            self.failing = false;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_kind_is_logged_once_per_period() {
        let mut l = Limiter::new(Duration::from_secs(3600));
        assert!(l.skipped("depth", "no valid pixel"));
        assert!(!l.skipped("depth", "no valid pixel"));
        assert!(l.skipped("encoding", "8UC3"));
        l.good();
        assert!(!l.failing);
        let mut l = Limiter::new(Duration::ZERO);
        assert!(l.skipped("depth", "a"));
        assert!(l.skipped("depth", "b"));
    }
}
