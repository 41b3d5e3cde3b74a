//! Outcomes of requests, tallied into HDR histograms (microseconds, 3 significant digits), and
//! the report of a run: counts by outcome, percentiles, the percentile spectrum and a sample of
//! latencies over time.

use std::collections::BTreeMap;
use std::sync::Mutex;
use std::time::Duration;

use hdrhistogram::Histogram;
use serde::{Deserialize, Serialize};
use tokio::time::Instant;

use super::frames::Frames;
use super::plan::Plan;
use super::{LoadConfig, Protocol};

/// Largest latency the histograms hold, microseconds (one hour); longer ones are clamped.
const MAX_US: u64 = 3_600_000_000;
/// Most latency samples kept for the plot over time; beyond, every other one is thinned out.
const MAX_SAMPLES: usize = 5_000;
/// Percentiles of the spectrum, as "nines" (`x` ↦ `100·(1 − 10^−x)`), in steps of this.
const SPECTRUM_STEP_NINES: f64 = 0.05;
/// The spectrum goes up to 99.99%.
const SPECTRUM_MAX_NINES: f64 = 4.0;

/// What became of one request.
#[derive(Debug, Clone, PartialEq, Eq)]
pub(crate) enum Outcome {
    /// A result (HTTP 200, stream `Result`).
    Ok,
    /// Refused for overload (HTTP 429 or 503, a stream `Error` with a retryable code), with the
    /// error code the service gave.
    Refused(String),
    /// Skipped by the stream for a newer frame (`Dropped`).
    Dropped,
    /// Any other failure, by kind: `http 422 bad_image`, `connect`, `timeout`, `ws bad_image`.
    Error(String),
    /// Not sent: the client already had `max_in_flight` requests outstanding.
    ClientSaturated,
}

/// Kind of a latency sample.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum SampleKind {
    /// A result.
    Ok,
    /// A refusal.
    Refused,
    /// A dropped stream frame.
    Dropped,
    /// An error.
    Error,
}

/// One request's latency at its time in the measured window.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Sample {
    /// Intended send time, seconds from the start of the measured window.
    pub t_s: f64,
    /// Latency, milliseconds.
    pub ms: f64,
    /// What the answer was.
    pub kind: SampleKind,
}

/// Latency percentiles of one histogram, milliseconds.
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize, Deserialize)]
pub struct Percentiles {
    /// Values recorded.
    pub count: u64,
    /// Mean.
    pub mean_ms: f64,
    /// Median.
    pub p50_ms: f64,
    /// 90th percentile.
    pub p90_ms: f64,
    /// 99th percentile.
    pub p99_ms: f64,
    /// 99.9th percentile.
    pub p999_ms: f64,
    /// Largest value.
    pub max_ms: f64,
}

fn us_to_ms(us: u64) -> f64 {
    us as f64 / 1e3
}

impl Percentiles {
    /// The percentiles of `h` (microseconds); all zero when it is empty.
    pub fn of(h: &Histogram<u64>) -> Self {
        if h.is_empty() {
            return Self::default();
        }
        let q = |q: f64| us_to_ms(h.value_at_quantile(q));
        Self {
            count: h.len(),
            mean_ms: h.mean() / 1e3,
            p50_ms: q(0.5),
            p90_ms: q(0.9),
            p99_ms: q(0.99),
            p999_ms: q(0.999),
            max_ms: us_to_ms(h.max()),
        }
    }
}

/// `[percentile, ms]` points from 0% to 99.99% on a "nines" scale, then the maximum at 100%.
pub(crate) fn spectrum(h: &Histogram<u64>) -> Vec<[f64; 2]> {
    if h.is_empty() {
        return Vec::new();
    }
    let steps = (SPECTRUM_MAX_NINES / SPECTRUM_STEP_NINES).round() as u32;
    let mut points: Vec<[f64; 2]> = (0..=steps)
        .map(|k| {
            let nines = f64::from(k) * SPECTRUM_STEP_NINES;
            let q = 1.0 - 10f64.powf(-nines);
            [100.0 * q, us_to_ms(h.value_at_quantile(q))]
        })
        .collect();
    points.push([100.0, us_to_ms(h.max())]);
    points
}

/// A new histogram of microseconds, 3 significant digits.
pub(crate) fn histogram() -> Histogram<u64> {
    Histogram::new_with_bounds(1, MAX_US, 3)
        .expect("bounds 1..1 h with 3 digits are valid; this is a bug")
}

/// Records `d` in `h` (microseconds, at least 1, at most one hour).
pub(crate) fn record(h: &mut Histogram<u64>, d: Duration) {
    let us = u64::try_from(d.as_micros())
        .unwrap_or(MAX_US)
        .clamp(1, MAX_US);
    h.saturating_record(us);
}

/// Everything tallied so far.
struct Tally {
    ok: Histogram<u64>,
    refused: Histogram<u64>,
    refused_by_code: BTreeMap<String, u64>,
    errors_by_kind: BTreeMap<String, u64>,
    dropped: u64,
    client_saturated: u64,
    samples: Vec<Sample>,
    sample_every: u64,
    seen: u64,
    last_done: Option<Instant>,
}

/// Collects the outcomes of a run's measured window (requests intended before its start are
/// warm-up and left out).
pub(crate) struct Recorder {
    measure_from: Instant,
    tally: Mutex<Tally>,
}

impl Recorder {
    /// A recorder whose measured window starts at `measure_from`.
    pub(crate) fn new(measure_from: Instant) -> Self {
        Self {
            measure_from,
            tally: Mutex::new(Tally {
                ok: histogram(),
                refused: histogram(),
                refused_by_code: BTreeMap::new(),
                errors_by_kind: BTreeMap::new(),
                dropped: 0,
                client_saturated: 0,
                samples: Vec::new(),
                sample_every: 1,
                seen: 0,
                last_done: None,
            }),
        }
    }

    /// Records a request intended at `intended` that ended with `outcome` at `done`
    /// (latency `done − intended`); warm-up requests are ignored.
    pub(crate) fn record(&self, intended: Instant, done: Instant, outcome: Outcome) {
        if intended < self.measure_from {
            return;
        }
        let latency = done.saturating_duration_since(intended);
        let mut t = self.tally.lock().unwrap_or_else(|p| p.into_inner());
        let kind = match outcome {
            Outcome::Ok => {
                record(&mut t.ok, latency);
                SampleKind::Ok
            }
            Outcome::Refused(code) => {
                record(&mut t.refused, latency);
                *t.refused_by_code.entry(code).or_default() += 1;
                SampleKind::Refused
            }
            Outcome::Dropped => {
                t.dropped += 1;
                SampleKind::Dropped
            }
            Outcome::Error(kind) => {
                *t.errors_by_kind.entry(kind).or_default() += 1;
                SampleKind::Error
            }
            Outcome::ClientSaturated => {
                t.client_saturated += 1;
                return;
            }
        };
        t.last_done = Some(t.last_done.map_or(done, |l| l.max(done)));
        let t_s = intended.duration_since(self.measure_from).as_secs_f64();
        t.sample(Sample {
            t_s,
            ms: latency.as_secs_f64() * 1e3,
            kind,
        });
    }

    /// End of the last measured answer.
    pub(crate) fn last_done(&self) -> Option<Instant> {
        self.tally
            .lock()
            .unwrap_or_else(|p| p.into_inner())
            .last_done
    }

    /// The report over a measured window of `window_s` seconds.
    pub(crate) fn report(&self, meta: RunInfo, window_s: f64) -> Report {
        let t = self.tally.lock().unwrap_or_else(|p| p.into_inner());
        let refused = t.refused.len();
        let errors: u64 = t.errors_by_kind.values().sum();
        let ok = t.ok.len();
        let answered_s = t.last_done.map_or(0.0, |d| {
            d.saturating_duration_since(self.measure_from).as_secs_f64()
        });
        let span_s = window_s.max(answered_s);
        let mut samples = t.samples.clone();
        samples.sort_by(|a, b| a.t_s.total_cmp(&b.t_s));
        Report {
            run: meta,
            window_s,
            requests: ok + refused + t.dropped + errors + t.client_saturated,
            ok,
            refused,
            dropped: t.dropped,
            errors,
            client_saturated: t.client_saturated,
            refused_by_code: t.refused_by_code.clone(),
            errors_by_kind: t.errors_by_kind.clone(),
            answered_s,
            throughput_ok_per_s: if span_s > 0.0 {
                ok as f64 / span_s
            } else {
                0.0
            },
            latency_ms: Percentiles::of(&t.ok),
            refusal_latency_ms: Percentiles::of(&t.refused),
            spectrum_ok: spectrum(&t.ok),
            spectrum_refused: spectrum(&t.refused),
            samples,
        }
    }
}

impl Tally {
    /// Keeps every `sample_every`-th sample; when full, thins to every other one.
    fn sample(&mut self, s: Sample) {
        self.seen += 1;
        if !self.seen.is_multiple_of(self.sample_every) {
            return;
        }
        self.samples.push(s);
        if self.samples.len() >= MAX_SAMPLES {
            let mut i = 0u32;
            self.samples.retain(|_| {
                i += 1;
                i.is_multiple_of(2)
            });
            self.sample_every *= 2;
        }
    }
}

/// What a run was, for its report.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct RunInfo {
    /// HTTP or WebSocket.
    pub protocol: Protocol,
    /// `open` or `closed` loop.
    pub load: String,
    /// Endpoint loaded.
    pub url: String,
    /// Frames sent.
    pub frames: String,
    /// Open loop: intended requests per second.
    pub offered_rate_per_s: Option<f64>,
    /// Connections (closed loop: clients; HTTP open loop: not limited).
    pub connections: usize,
    /// Open loop: cap on outstanding requests.
    pub max_in_flight: usize,
    /// Warm-up before the measured window, seconds (not in any number of the report).
    pub warmup_s: f64,
    /// Start of the measured window, seconds since the Unix epoch.
    #[serde(default)]
    pub window_start_unix_s: f64,
}

impl RunInfo {
    /// What the run of `cfg` loading `url` with `frames` on the schedule `plan` was; the
    /// measured window's start as `plan` places it now.
    pub(crate) fn new(cfg: &LoadConfig, url: String, frames: &Frames, plan: &Plan) -> Self {
        Self {
            protocol: cfg.protocol,
            load: if cfg.rate_per_s().is_some() {
                "open"
            } else {
                "closed"
            }
            .into(),
            url,
            frames: frames.description.clone(),
            offered_rate_per_s: cfg.rate_per_s(),
            connections: cfg.connections,
            max_in_flight: cfg.max_in_flight,
            warmup_s: cfg.warmup.as_secs_f64(),
            window_start_unix_s: plan.window_start_unix_s(),
        }
    }
}

/// The result of one run: what was offered, what came back and how fast.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Report {
    /// What the run was (its fields sit at the top level of the JSON).
    #[serde(flatten)]
    pub run: RunInfo,
    /// Measured window, seconds (open loop: the span of intended send times).
    pub window_s: f64,
    /// Requests due in the window (every outcome, `client_saturated` included).
    pub requests: u64,
    /// Results.
    pub ok: u64,
    /// Refusals (429, 503, retryable stream errors).
    pub refused: u64,
    /// Stream frames dropped for newer ones.
    pub dropped: u64,
    /// Other failures.
    pub errors: u64,
    /// Requests not sent because `max_in_flight` were outstanding.
    pub client_saturated: u64,
    /// Refusals by error code.
    pub refused_by_code: BTreeMap<String, u64>,
    /// Errors by kind.
    pub errors_by_kind: BTreeMap<String, u64>,
    /// From the start of the window to the last answer, seconds (beyond `window_s` when the
    /// service was behind).
    pub answered_s: f64,
    /// Results per second, over the window or until the last answer if that came later (so an
    /// overloaded service is not credited with the offered rate).
    pub throughput_ok_per_s: f64,
    /// Latency of results, from the intended send time.
    pub latency_ms: Percentiles,
    /// Latency of refusals (how fast overload is answered).
    pub refusal_latency_ms: Percentiles,
    /// `[percentile, ms]` of results, 0 to 99.99% on a nines scale, then 100% (the maximum).
    pub spectrum_ok: Vec<[f64; 2]>,
    /// The same for refusals.
    pub spectrum_refused: Vec<[f64; 2]>,
    /// Latencies over time, thinned to at most a few thousand.
    pub samples: Vec<Sample>,
}

impl Report {
    /// Reads a report written by [`Report::to_json`].
    pub fn from_json(text: &str) -> Result<Self, serde_json::Error> {
        serde_json::from_str(text)
    }

    /// The report as pretty JSON.
    pub fn to_json(&self) -> String {
        serde_json::to_string_pretty(self).expect("a report always serialises; this is a bug")
    }

    /// A short name: `http open 10/s` or `ws closed ×2`.
    pub fn label(&self) -> String {
        let run = &self.run;
        match run.offered_rate_per_s {
            Some(r) => format!("{} {} {}/s", run.protocol.as_str(), run.load, fmt_rate(r)),
            None => format!(
                "{} {} ×{}",
                run.protocol.as_str(),
                run.load,
                run.connections
            ),
        }
    }
}

/// A rate without needless decimals (`10`, `12.5`).
pub(crate) fn fmt_rate(r: f64) -> String {
    if (r - r.round()).abs() < 1e-9 {
        format!("{}", r.round())
    } else {
        format!("{r:.2}")
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use approx::assert_relative_eq;

    #[test]
    fn percentiles_of_a_uniform_spread_hold_three_digits() {
        let mut h = histogram();
        for ms in 1..=1000u64 {
            record(&mut h, Duration::from_millis(ms));
        }
        let p = Percentiles::of(&h);
        assert_eq!(p.count, 1000);
        assert_relative_eq!(p.p50_ms, 500.0, max_relative = 1e-3);
        assert_relative_eq!(p.p90_ms, 900.0, max_relative = 1e-3);
        assert_relative_eq!(p.p99_ms, 990.0, max_relative = 1e-3);
        assert_relative_eq!(p.p999_ms, 999.0, max_relative = 1e-3);
        assert_relative_eq!(p.max_ms, 1000.0, max_relative = 1e-3);
        assert_relative_eq!(p.mean_ms, 500.5, max_relative = 1e-3);
        let s = spectrum(&h);
        assert_eq!(s.first().map(|p| p[0]), Some(0.0));
        assert!(s
            .windows(2)
            .all(|w| w[0][0] < w[1][0] && w[0][1] <= w[1][1]));
        assert_relative_eq!(s[s.len() - 2][0], 99.99, max_relative = 1e-9);
    }

    #[test]
    fn one_slow_value_in_a_hundred_sets_the_max_not_the_p99() {
        let mut h = histogram();
        for _ in 0..999 {
            record(&mut h, Duration::from_millis(10));
        }
        record(&mut h, Duration::from_secs(2));
        let p = Percentiles::of(&h);
        assert_relative_eq!(p.p99_ms, 10.0, max_relative = 1e-3);
        assert_relative_eq!(p.max_ms, 2000.0, max_relative = 1e-3);
        assert_eq!(Percentiles::of(&histogram()), Percentiles::default());
    }

    #[test]
    fn warm_up_is_left_out_and_outcomes_are_counted_by_kind() {
        let t0 = Instant::now();
        let from = t0 + Duration::from_secs(1);
        let rec = Recorder::new(from);
        let ms = |m| Duration::from_millis(m);
        rec.record(t0, t0 + ms(5), Outcome::Ok);
        rec.record(from, from + ms(100), Outcome::Ok);
        rec.record(from, from + ms(2), Outcome::Refused("overloaded".into()));
        rec.record(
            from,
            from + ms(2),
            Outcome::Error("http 422 bad_image".into()),
        );
        rec.record(from, from, Outcome::ClientSaturated);
        rec.record(from, from + ms(2), Outcome::Dropped);
        let info = RunInfo {
            protocol: Protocol::Http,
            load: "open".into(),
            url: "u".into(),
            frames: "f".into(),
            offered_rate_per_s: Some(5.0),
            connections: 1,
            max_in_flight: 1,
            warmup_s: 1.0,
            window_start_unix_s: 0.0,
        };
        let r = rec.report(info, 2.0);
        assert_eq!(
            (
                r.requests,
                r.ok,
                r.refused,
                r.errors,
                r.client_saturated,
                r.dropped
            ),
            (5, 1, 1, 1, 1, 1)
        );
        assert_relative_eq!(r.latency_ms.p50_ms, 100.0, max_relative = 1e-3);
        assert_relative_eq!(r.refusal_latency_ms.max_ms, 2.0, max_relative = 1e-3);
        assert_eq!(r.errors_by_kind.get("http 422 bad_image"), Some(&1));
        assert_relative_eq!(r.throughput_ok_per_s, 0.5);
        assert_relative_eq!(r.answered_s, 0.1, max_relative = 1e-6);
        assert_eq!(r.samples.len(), 4);
    }

    #[test]
    fn samples_are_thinned_not_unbounded() {
        let t0 = Instant::now();
        let rec = Recorder::new(t0);
        for i in 0..(3 * MAX_SAMPLES as u64) {
            let t = t0 + Duration::from_millis(i);
            rec.record(t, t + Duration::from_millis(1), Outcome::Ok);
        }
        let info = RunInfo {
            protocol: Protocol::Ws,
            load: "closed".into(),
            url: String::new(),
            frames: String::new(),
            offered_rate_per_s: None,
            connections: 1,
            max_in_flight: 1,
            warmup_s: 0.0,
            window_start_unix_s: 0.0,
        };
        let r = rec.report(info, 1.0);
        assert!(r.samples.len() < MAX_SAMPLES && r.samples.len() > MAX_SAMPLES / 4);
        assert_eq!(r.ok, 3 * MAX_SAMPLES as u64);
    }
}
