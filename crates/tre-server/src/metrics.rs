//! Prometheus metrics of the service, kept in a `prometheus-client` registry and written in the
//! Prometheus text exposition format (0.0.4) by `GET /metrics`: requests by outcome, queue
//! depth, latency histograms per stage, frames dropped, batch sizes.
//!
//! A labelled family (`tre_requests_total`, `tre_request_seconds`, `tre_stage_seconds`) is
//! written from its first series on: the encoder writes no `# HELP`/`# TYPE` lines for an
//! empty one, which Prometheus reads the same as no samples.

use std::time::Duration;

use prometheus_client::encoding::EncodeLabelSet;
use prometheus_client::metrics::counter::Counter;
use prometheus_client::metrics::family::Family;
use prometheus_client::metrics::gauge::Gauge;
use prometheus_client::metrics::histogram::Histogram;
use prometheus_client::registry::Registry;

use tre_pipeline::StageTimings;

/// Upper bounds of the latency buckets, seconds.
const LATENCY_BUCKETS_S: [f64; 14] = [
    0.001, 0.0025, 0.005, 0.01, 0.025, 0.05, 0.075, 0.1, 0.15, 0.25, 0.5, 1.0, 2.5, 10.0,
];
/// Upper bounds of the batch-size buckets.
const BATCH_BUCKETS: [f64; 5] = [1.0, 2.0, 4.0, 8.0, 16.0];

/// A histogram over [`LATENCY_BUCKETS_S`].
fn latency_histogram() -> Histogram {
    Histogram::new(LATENCY_BUCKETS_S)
}

/// Labels of `tre_requests_total`.
#[derive(Debug, Clone, PartialEq, Eq, Hash, EncodeLabelSet)]
struct RequestLabels {
    endpoint: &'static str,
    outcome: &'static str,
}

/// Labels of `tre_request_seconds`.
#[derive(Debug, Clone, PartialEq, Eq, Hash, EncodeLabelSet)]
struct EndpointLabels {
    endpoint: &'static str,
}

/// Labels of `tre_stage_seconds`.
#[derive(Debug, Clone, PartialEq, Eq, Hash, EncodeLabelSet)]
struct StageLabels {
    stage: &'static str,
}

/// Latency histograms by label set, each made with [`latency_histogram`].
type Latencies<L> = Family<L, Histogram, fn() -> Histogram>;

/// Every metric of the service, and the registry that writes them.
#[derive(Debug)]
pub(crate) struct Metrics {
    registry: Registry,
    ready: Gauge,
    workers: Gauge,
    queue_depth: Gauge,
    queue_capacity: Gauge,
    streams_open: Gauge,
    connections_open: Gauge,
    connections_refused: Counter,
    requests: Family<RequestLabels, Counter>,
    frames_dropped: Counter,
    request_seconds: Latencies<EndpointLabels>,
    stage_seconds: Latencies<StageLabels>,
    queue_wait: Histogram,
    batch_size: Histogram,
}

impl Default for Metrics {
    fn default() -> Self {
        let mut m = Self {
            registry: Registry::default(),
            ready: Gauge::default(),
            workers: Gauge::default(),
            queue_depth: Gauge::default(),
            queue_capacity: Gauge::default(),
            streams_open: Gauge::default(),
            connections_open: Gauge::default(),
            connections_refused: Counter::default(),
            requests: Family::default(),
            frames_dropped: Counter::default(),
            request_seconds: Family::new_with_constructor(latency_histogram),
            stage_seconds: Family::new_with_constructor(latency_histogram),
            queue_wait: latency_histogram(),
            batch_size: Histogram::new(BATCH_BUCKETS),
        };
        m.register();
        m
    }
}

/// Gauges read at scrape time.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Gauges {
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
    /// Registers every metric, in the order the exposition lists them. Help texts have no
    /// final full stop: the registry adds one. Counters are registered without `_total`: the
    /// encoder adds it.
    fn register(&mut self) {
        let r = &mut self.registry;
        r.register(
            "tre_ready",
            "1 once every worker has warmed up",
            self.ready.clone(),
        );
        r.register(
            "tre_workers",
            "Inference worker threads",
            self.workers.clone(),
        );
        r.register(
            "tre_queue_depth",
            "Jobs waiting for a worker",
            self.queue_depth.clone(),
        );
        r.register(
            "tre_queue_capacity",
            "Capacity of the job queue",
            self.queue_capacity.clone(),
        );
        r.register(
            "tre_streams_open",
            "Open WebSocket streams",
            self.streams_open.clone(),
        );
        r.register(
            "tre_connections_open",
            "Open HTTP connections (a stream counts until its upgrade)",
            self.connections_open.clone(),
        );
        r.register(
            "tre_connections_refused",
            "Connections refused over --max-connections",
            self.connections_refused.clone(),
        );
        self.register_families();
    }

    /// Registers the labelled families and the histograms.
    fn register_families(&mut self) {
        let r = &mut self.registry;
        r.register(
            "tre_requests",
            "Requests and stream frames by endpoint and outcome",
            self.requests.clone(),
        );
        r.register(
            "tre_frames_dropped",
            "Stream frames skipped for a newer one",
            self.frames_dropped.clone(),
        );
        r.register(
            "tre_request_seconds",
            "Latency from arrival to answer, of requests answered with a map",
            self.request_seconds.clone(),
        );
        r.register(
            "tre_stage_seconds",
            "Wall time of each pipeline stage",
            self.stage_seconds.clone(),
        );
        r.register(
            "tre_queue_wait_seconds",
            "Time frames answered with a map waited for a worker",
            self.queue_wait.clone(),
        );
        r.register(
            "tre_batch_size",
            "Frames per worker run (every run, failed frames included)",
            self.batch_size.clone(),
        );
    }

    /// Counts one request to `endpoint` (`roughness`, `stream`) with `outcome` (`ok` or an
    /// error code) and, when it ran, its total latency.
    pub(crate) fn request(
        &self,
        endpoint: &'static str,
        outcome: &'static str,
        took: Option<Duration>,
    ) {
        self.requests
            .get_or_create(&RequestLabels { endpoint, outcome })
            .inc();
        if let Some(took) = took {
            self.request_seconds
                .get_or_create(&EndpointLabels { endpoint })
                .observe(took.as_secs_f64());
        }
    }

    /// Records the stage timings of one frame, and its wait in the queue.
    pub(crate) fn frame(&self, timings: &StageTimings, queued: Duration) {
        for (stage, took) in timings.iter() {
            self.stage_seconds
                .get_or_create(&StageLabels { stage })
                .observe(took.as_secs_f64());
        }
        self.queue_wait.observe(queued.as_secs_f64());
    }

    /// Records the size of one batch run by a worker.
    pub(crate) fn batch(&self, size: usize) {
        self.batch_size.observe(size as f64);
    }

    /// Counts a stream frame dropped because a newer one arrived.
    pub(crate) fn dropped(&self) {
        self.frames_dropped.inc();
    }

    /// A stream opened (`+1`) or closed (`-1`).
    pub(crate) fn stream_open(&self, open: bool) {
        if open {
            self.streams_open.inc();
        } else {
            self.streams_open.dec();
        }
    }

    /// An HTTP connection taken (`+1`) or closed (`-1`) within `--max-connections`.
    pub(crate) fn connection_open(&self, open: bool) {
        if open {
            self.connections_open.inc();
        } else {
            self.connections_open.dec();
        }
    }

    /// Counts a connection refused for `--max-connections`.
    pub(crate) fn connection_refused(&self) {
        self.connections_refused.inc();
    }

    /// The exposition text, with the gauges read at scrape time set from `g`.
    pub(crate) fn render(&self, g: Gauges) -> String {
        let count = |n: usize| i64::try_from(n).unwrap_or(i64::MAX);
        self.ready.set(i64::from(g.ready));
        self.workers.set(count(g.workers));
        self.queue_depth.set(count(g.queue_depth));
        self.queue_capacity.set(count(g.queue_capacity));
        let mut out = String::with_capacity(8192);
        prometheus_client::encoding::prometheus_text::encode(&mut out, &self.registry)
            .expect("writing into a String does not fail; this is a bug");
        out
    }
}

#[cfg(test)]
mod tests;
