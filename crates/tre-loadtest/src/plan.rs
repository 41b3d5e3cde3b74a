//! When a run starts, when its measured window starts, and when it stops: after its duration
//! or its number of measured requests, whichever comes first.

use std::sync::atomic::{AtomicU64, Ordering};
use std::time::Duration;

use tokio::time::Instant;

use super::LoadConfig;

/// Lead time before the first intended send, so that setting up does not eat into it.
const LEAD: Duration = Duration::from_millis(20);

/// The schedule of a run.
#[derive(Debug)]
pub(crate) struct Plan {
    /// Intended time of the first request.
    pub t0: Instant,
    /// Start of the measured window (`t0` + warm-up).
    pub measure_from: Instant,
    /// No request is due at or after this.
    end: Option<Instant>,
    /// Most measured requests.
    max_requests: Option<u64>,
    /// Measured requests admitted so far.
    measured: AtomicU64,
}

impl Plan {
    /// The plan of `cfg` starting now.
    pub(crate) fn new(cfg: &LoadConfig) -> Self {
        let t0 = Instant::now() + LEAD;
        let measure_from = t0 + cfg.warmup;
        Self {
            t0,
            measure_from,
            end: cfg.duration.map(|d| measure_from + d),
            max_requests: cfg.requests,
            measured: AtomicU64::new(0),
        }
    }

    /// Intended send time of request `i` at `rate_per_s`.
    pub(crate) fn intended(&self, i: u64, rate_per_s: f64) -> Instant {
        self.t0 + Duration::from_secs_f64(i as f64 / rate_per_s)
    }

    /// Whether a request intended at `t` is part of the run: `None` once the run is over, else
    /// whether it is measured (`false`: warm-up).
    pub(crate) fn admit(&self, t: Instant) -> Option<bool> {
        if self.end.is_some_and(|end| t >= end) {
            return None;
        }
        if t < self.measure_from {
            return Some(false);
        }
        let n = self.measured.fetch_add(1, Ordering::Relaxed);
        if self.max_requests.is_some_and(|max| n >= max) {
            self.measured.fetch_sub(1, Ordering::Relaxed);
            return None;
        }
        Some(true)
    }

    /// Start of the measured window, seconds since the Unix epoch (to line runs up with other
    /// records of the machine).
    pub(crate) fn window_start_unix_s(&self) -> f64 {
        let now = std::time::SystemTime::now()
            .duration_since(std::time::UNIX_EPOCH)
            .map_or(0.0, |d| d.as_secs_f64());
        let ahead = self.measure_from.saturating_duration_since(Instant::now());
        let behind = Instant::now().saturating_duration_since(self.measure_from);
        now + ahead.as_secs_f64() - behind.as_secs_f64()
    }

    /// Measured requests admitted.
    pub(crate) fn measured(&self) -> u64 {
        self.measured.load(Ordering::Relaxed)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_run_stops_at_its_duration_or_its_requests_whichever_first() {
        let cfg = LoadConfig {
            duration: Some(Duration::from_secs(1)),
            requests: Some(3),
            warmup: Duration::from_secs(1),
            ..LoadConfig::default()
        };
        let plan = Plan::new(&cfg);
        assert_eq!(plan.admit(plan.t0), Some(false), "warm-up");
        let at = |ms| plan.measure_from + Duration::from_millis(ms);
        assert_eq!(plan.admit(at(0)), Some(true));
        assert_eq!(plan.admit(at(999)), Some(true));
        assert_eq!(plan.admit(at(1000)), None, "past the duration");
        assert_eq!(plan.admit(at(10)), Some(true));
        assert_eq!(plan.admit(at(20)), None, "past the requests");
        assert_eq!(plan.measured(), 3);
        let i = plan.intended(10, 4.0);
        assert_eq!(i - plan.t0, Duration::from_millis(2500));
    }
}
