//! Prometheus metrics of the service, kept in atomics and written in the text exposition format
//! by `GET /metrics`: requests by outcome, queue depth, latency histograms per stage, frames
//! dropped, batch sizes.

use std::collections::BTreeMap;
use std::fmt::Write;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::Mutex;
use std::time::Duration;

use tre_pipeline::StageTimings;

/// Upper bounds of the latency buckets, seconds.
const LATENCY_BUCKETS_S: [f64; 14] = [
    0.001, 0.0025, 0.005, 0.01, 0.025, 0.05, 0.075, 0.1, 0.15, 0.25, 0.5, 1.0, 2.5, 10.0,
];
/// Upper bounds of the batch-size buckets.
const BATCH_BUCKETS: [f64; 5] = [1.0, 2.0, 4.0, 8.0, 16.0];

/// A cumulative histogram with fixed buckets.
#[derive(Debug)]
struct Histogram {
    bounds: &'static [f64],
    counts: Vec<AtomicU64>,
    /// Sum of observations, in millionths of the unit.
    sum_micro: AtomicU64,
    count: AtomicU64,
}

impl Histogram {
    fn new(bounds: &'static [f64]) -> Self {
        Self {
            bounds,
            counts: bounds.iter().map(|_| AtomicU64::new(0)).collect(),
            sum_micro: AtomicU64::new(0),
            count: AtomicU64::new(0),
        }
    }

    fn observe(&self, v: f64) {
        if let Some(i) = self.bounds.iter().position(|&b| v <= b) {
            self.counts[i].fetch_add(1, Ordering::Relaxed);
        }
        self.sum_micro
            .fetch_add((v.max(0.0) * 1e6).round() as u64, Ordering::Relaxed);
        self.count.fetch_add(1, Ordering::Relaxed);
    }

    fn write(&self, out: &mut String, name: &str, labels: &str) {
        let sep = if labels.is_empty() { "" } else { "," };
        let mut cumulative = 0;
        for (b, c) in self.bounds.iter().zip(&self.counts) {
            cumulative += c.load(Ordering::Relaxed);
            let _ = writeln!(out, "{name}_bucket{{{labels}{sep}le=\"{b}\"}} {cumulative}");
        }
        let count = self.count.load(Ordering::Relaxed);
        let _ = writeln!(out, "{name}_bucket{{{labels}{sep}le=\"+Inf\"}} {count}");
        let sum = self.sum_micro.load(Ordering::Relaxed) as f64 / 1e6;
        let braces = |s: &str| {
            if s.is_empty() {
                String::new()
            } else {
                format!("{{{s}}}")
            }
        };
        let _ = writeln!(out, "{name}_sum{} {sum}", braces(labels));
        let _ = writeln!(out, "{name}_count{} {count}", braces(labels));
    }
}

/// Every metric of the service.
#[derive(Debug)]
pub struct Metrics {
    requests: Mutex<BTreeMap<(&'static str, &'static str), u64>>,
    request_seconds: Mutex<BTreeMap<&'static str, Histogram>>,
    stage_seconds: Mutex<BTreeMap<&'static str, Histogram>>,
    queue_wait: Histogram,
    batch_size: Histogram,
    frames_dropped: AtomicU64,
    streams_open: AtomicU64,
    connections_open: AtomicU64,
    connections_refused: AtomicU64,
}

impl Default for Metrics {
    fn default() -> Self {
        Self {
            requests: Mutex::default(),
            request_seconds: Mutex::default(),
            stage_seconds: Mutex::default(),
            queue_wait: Histogram::new(&LATENCY_BUCKETS_S),
            batch_size: Histogram::new(&BATCH_BUCKETS),
            frames_dropped: AtomicU64::new(0),
            streams_open: AtomicU64::new(0),
            connections_open: AtomicU64::new(0),
            connections_refused: AtomicU64::new(0),
        }
    }
}

/// Gauges read at scrape time.
#[derive(Debug, Clone, Copy)]
pub struct Gauges {
    /// Jobs waiting for a worker.
    pub queue_depth: usize,
    /// Queue capacity.
    pub queue_capacity: usize,
    /// Worker threads.
    pub workers: usize,
    /// Whether every worker has loaded and warmed up its models.
    pub ready: bool,
}

impl Metrics {
    /// Counts one request to `endpoint` (`roughness`, `stream`) with `outcome` (`ok` or an
    /// error code) and, when it ran, its total latency.
    pub fn request(&self, endpoint: &'static str, outcome: &'static str, took: Option<Duration>) {
        let mut map = self.requests.lock().unwrap_or_else(|p| p.into_inner());
        *map.entry((endpoint, outcome)).or_default() += 1;
        drop(map);
        if let Some(took) = took {
            let mut map = self
                .request_seconds
                .lock()
                .unwrap_or_else(|p| p.into_inner());
            map.entry(endpoint)
                .or_insert_with(|| Histogram::new(&LATENCY_BUCKETS_S))
                .observe(took.as_secs_f64());
        }
    }

    /// Records the stage timings of one frame, and its wait in the queue.
    pub fn frame(&self, timings: &StageTimings, queued: Duration) {
        let mut map = self.stage_seconds.lock().unwrap_or_else(|p| p.into_inner());
        for (stage, took) in timings.iter() {
            map.entry(stage)
                .or_insert_with(|| Histogram::new(&LATENCY_BUCKETS_S))
                .observe(took.as_secs_f64());
        }
        drop(map);
        self.queue_wait.observe(queued.as_secs_f64());
    }

    /// Records the size of one batch run by a worker.
    pub fn batch(&self, size: usize) {
        self.batch_size.observe(size as f64);
    }

    /// Counts a stream frame dropped because a newer one arrived.
    pub fn dropped(&self) {
        self.frames_dropped.fetch_add(1, Ordering::Relaxed);
    }

    /// A stream opened (`+1`) or closed (`-1`).
    pub fn stream_open(&self, open: bool) {
        if open {
            self.streams_open.fetch_add(1, Ordering::Relaxed);
        } else {
            self.streams_open.fetch_sub(1, Ordering::Relaxed);
        }
    }

    /// An HTTP connection taken (`+1`) or closed (`-1`) within `--max-connections`.
    pub fn connection_open(&self, open: bool) {
        if open {
            self.connections_open.fetch_add(1, Ordering::Relaxed);
        } else {
            self.connections_open.fetch_sub(1, Ordering::Relaxed);
        }
    }

    /// Counts a connection refused for `--max-connections`.
    pub fn connection_refused(&self) {
        self.connections_refused.fetch_add(1, Ordering::Relaxed);
    }

    /// The exposition text.
    pub fn render(&self, g: Gauges) -> String {
        let mut out = String::with_capacity(8192);
        let gauge = |out: &mut String, name: &str, help: &str, v: f64| {
            let _ = writeln!(out, "# HELP {name} {help}\n# TYPE {name} gauge\n{name} {v}");
        };
        gauge(
            &mut out,
            "tre_ready",
            "1 once every worker has warmed up.",
            f64::from(u8::from(g.ready)),
        );
        gauge(
            &mut out,
            "tre_workers",
            "Inference worker threads.",
            g.workers as f64,
        );
        gauge(
            &mut out,
            "tre_queue_depth",
            "Jobs waiting for a worker.",
            g.queue_depth as f64,
        );
        gauge(
            &mut out,
            "tre_queue_capacity",
            "Capacity of the job queue.",
            g.queue_capacity as f64,
        );
        let open = self.streams_open.load(Ordering::Relaxed) as f64;
        gauge(
            &mut out,
            "tre_streams_open",
            "Open WebSocket streams.",
            open,
        );
        let connections = self.connections_open.load(Ordering::Relaxed) as f64;
        gauge(
            &mut out,
            "tre_connections_open",
            "Open HTTP connections (a stream counts until its upgrade).",
            connections,
        );
        let refused = self.connections_refused.load(Ordering::Relaxed);
        let _ = writeln!(out, "# HELP tre_connections_refused_total Connections refused over --max-connections.\n# TYPE tre_connections_refused_total counter\ntre_connections_refused_total {refused}");
        out.push_str("# HELP tre_requests_total Requests and stream frames by endpoint and outcome.\n# TYPE tre_requests_total counter\n");
        for ((endpoint, outcome), n) in self
            .requests
            .lock()
            .unwrap_or_else(|p| p.into_inner())
            .iter()
        {
            let _ = writeln!(
                out,
                "tre_requests_total{{endpoint=\"{endpoint}\",outcome=\"{outcome}\"}} {n}"
            );
        }
        let dropped = self.frames_dropped.load(Ordering::Relaxed);
        let _ = writeln!(out, "# HELP tre_frames_dropped_total Stream frames skipped for a newer one.\n# TYPE tre_frames_dropped_total counter\ntre_frames_dropped_total {dropped}");
        out.push_str("# HELP tre_request_seconds Latency from arrival to answer, of requests answered with a map.\n# TYPE tre_request_seconds histogram\n");
        for (endpoint, h) in self
            .request_seconds
            .lock()
            .unwrap_or_else(|p| p.into_inner())
            .iter()
        {
            h.write(
                &mut out,
                "tre_request_seconds",
                &format!("endpoint=\"{endpoint}\""),
            );
        }
        out.push_str("# HELP tre_stage_seconds Wall time of each pipeline stage.\n# TYPE tre_stage_seconds histogram\n");
        for (stage, h) in self
            .stage_seconds
            .lock()
            .unwrap_or_else(|p| p.into_inner())
            .iter()
        {
            h.write(&mut out, "tre_stage_seconds", &format!("stage=\"{stage}\""));
        }
        out.push_str("# HELP tre_queue_wait_seconds Time frames answered with a map waited for a worker.\n# TYPE tre_queue_wait_seconds histogram\n");
        self.queue_wait
            .write(&mut out, "tre_queue_wait_seconds", "");
        out.push_str(
            "# HELP tre_batch_size Frames per worker run (every run, failed frames included).\n# TYPE tre_batch_size histogram\n",
        );
        self.batch_size.write(&mut out, "tre_batch_size", "");
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn histograms_are_cumulative_and_counted() {
        let m = Metrics::default();
        m.request("roughness", "ok", Some(Duration::from_millis(30)));
        m.request("roughness", "ok", Some(Duration::from_millis(300)));
        m.request("roughness", "bad_image", None);
        let text = m.render(Gauges {
            queue_depth: 3,
            queue_capacity: 8,
            workers: 2,
            ready: true,
        });
        assert!(text.contains("tre_requests_total{endpoint=\"roughness\",outcome=\"ok\"} 2"));
        assert!(text.contains("tre_requests_total{endpoint=\"roughness\",outcome=\"bad_image\"} 1"));
        assert!(text.contains("tre_request_seconds_bucket{endpoint=\"roughness\",le=\"0.05\"} 1"));
        assert!(text.contains("tre_request_seconds_bucket{endpoint=\"roughness\",le=\"0.5\"} 2"));
        assert!(text.contains("tre_request_seconds_count{endpoint=\"roughness\"} 2"));
        assert!(text.contains("tre_queue_depth 3"));
    }
}
