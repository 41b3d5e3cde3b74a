//! A recording's counts and latencies, and the progress line they make.

use std::fmt;
use std::time::{Duration, Instant};

use hdrhistogram::Histogram;

use crate::{FrameResult, StreamMap};

/// The counts of a recording at one moment; displays as `tre client`'s progress line.
#[derive(Debug, Clone, PartialEq)]
pub struct Progress {
    /// Time since the recording started.
    pub elapsed: Duration,
    /// Frames sent.
    pub sent: u64,
    /// Frames with a result.
    pub results: u64,
    /// Frames the server skipped.
    pub dropped: u64,
    /// Errors (for a frame or not).
    pub errors: u64,
    /// Frames that got no answer.
    pub lost: u64,
    /// Median and 99th-percentile latency of the results, milliseconds (`None` before the
    /// first).
    pub latency_p50_p99_ms: Option<(f64, f64)>,
    /// Results per second: since the previous progress line, or over the whole recording for
    /// the final counts.
    pub fps: f64,
    /// The final counts of the recording rather than a progress line.
    pub done: bool,
}

impl fmt::Display for Progress {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "{}[{:6.1} s] sent {}, results {}, dropped {}, errors {}, lost {}",
            if self.done { "done " } else { "" },
            self.elapsed.as_secs_f64(),
            self.sent,
            self.results,
            self.dropped,
            self.errors,
            self.lost
        )?;
        if let Some((p50, p99)) = self.latency_p50_p99_ms {
            write!(f, ", latency p50 {p50:.1} ms p99 {p99:.1} ms")?;
        }
        write!(f, ", {:.1} fps", self.fps)
    }
}

/// Counts and latencies so far.
pub(super) struct Stats {
    start: Instant,
    /// Frames with a result.
    pub results: u64,
    /// Frames the server skipped.
    pub dropped: u64,
    /// Errors.
    pub errors: u64,
    /// Frames that got no answer.
    pub lost: u64,
    latency_us: Histogram<u64>,
    last: (Instant, u64),
    /// Why the session gave up, if it did.
    pub gave_up: Option<std::sync::Arc<crate::ClientError>>,
    /// The latest map the server sent, if the session asked for one.
    pub map: Option<Box<StreamMap>>,
}

impl Stats {
    /// Nothing counted yet; the clock starts now.
    pub(super) fn new() -> Self {
        let now = Instant::now();
        Self {
            start: now,
            results: 0,
            dropped: 0,
            errors: 0,
            lost: 0,
            latency_us: Histogram::new_with_bounds(1, 3_600_000_000, 3)
                .expect("bounds and 3 significant figures are valid; this is a bug"),
            last: (now, 0),
            gave_up: None,
            map: None,
        }
    }

    /// Counts a result and its latency.
    pub(super) fn result(&mut self, r: &FrameResult) {
        self.results += 1;
        let us = u64::try_from(r.latency.as_micros()).unwrap_or(u64::MAX);
        self.latency_us.saturating_record(us.max(1));
    }

    /// The counts now with `sent` frames sent: a progress line (`live`: fps since the previous
    /// one) or the final counts (fps over the recording).
    pub(super) fn progress(&mut self, sent: u64, live: bool) -> Progress {
        let now = Instant::now();
        let (since, count) = if live { self.last } else { (self.start, 0) };
        let secs = now.duration_since(since).as_secs_f64().max(1e-9);
        let fps = (self.results - count) as f64 / secs;
        self.last = (now, self.results);
        let q = |p| self.latency_us.value_at_quantile(p) as f64 / 1e3;
        Progress {
            elapsed: now.duration_since(self.start),
            sent,
            results: self.results,
            dropped: self.dropped,
            errors: self.errors,
            lost: self.lost,
            latency_p50_p99_ms: (self.results > 0).then(|| (q(0.5), q(0.99))),
            fps,
            done: !live,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_progress_line_shows_latency_once_there_are_results() {
        let mut p = Progress {
            elapsed: Duration::from_millis(2500),
            sent: 7,
            results: 0,
            dropped: 1,
            errors: 2,
            lost: 3,
            latency_p50_p99_ms: None,
            fps: 0.0,
            done: false,
        };
        assert_eq!(
            p.to_string(),
            "[   2.5 s] sent 7, results 0, dropped 1, errors 2, lost 3, 0.0 fps"
        );
        p.results = 1;
        p.latency_p50_p99_ms = Some((12.34, 56.0));
        p.fps = 0.4;
        p.done = true;
        assert_eq!(
            p.to_string(),
            "done [   2.5 s] sent 7, results 1, dropped 1, errors 2, lost 3, latency p50 12.3 ms p99 56.0 ms, 0.4 fps"
        );
    }
}
