//! Tests of the exposition: names, types, help texts, labels and values.

use super::*;

fn gauges() -> Gauges {
    Gauges {
        queue_depth: 3,
        queue_capacity: 8,
        workers: 2,
        ready: true,
    }
}

#[test]
fn histograms_are_cumulative_and_counted() {
    let m = Metrics::default();
    m.request("roughness", "ok", Some(Duration::from_millis(30)));
    m.request("roughness", "ok", Some(Duration::from_millis(300)));
    m.request("roughness", "bad_image", None);
    let text = m.render(gauges());
    assert!(text.contains("tre_requests_total{endpoint=\"roughness\",outcome=\"ok\"} 2"));
    assert!(text.contains("tre_requests_total{endpoint=\"roughness\",outcome=\"bad_image\"} 1"));
    assert!(text.contains("tre_request_seconds_bucket{endpoint=\"roughness\",le=\"0.05\"} 1"));
    assert!(text.contains("tre_request_seconds_bucket{endpoint=\"roughness\",le=\"0.5\"} 2"));
    assert!(text.contains("tre_request_seconds_bucket{endpoint=\"roughness\",le=\"+Inf\"} 2"));
    let sum = sample(&text, "tre_request_seconds_sum{endpoint=\"roughness\"}");
    assert!((sum - 0.33).abs() < 1e-9, "{sum}");
    assert!(text.contains("tre_request_seconds_count{endpoint=\"roughness\"} 2"));
    assert!(text.contains("tre_queue_depth 3"));
}

/// The value of the sample `series` (name and labels) in `text`.
fn sample(text: &str, series: &str) -> f64 {
    text.lines()
        .find_map(|l| l.strip_prefix(series)?.strip_prefix(' '))
        .and_then(|v| v.parse().ok())
        .unwrap_or_else(|| panic!("no sample {series}:\n{text}"))
}

/// Every metric with its type and help text, as the exposition writes them.
const EVERY_METRIC: [(&str, &str, &str); 13] = [
    ("tre_ready", "gauge", "1 once every worker has warmed up."),
    ("tre_workers", "gauge", "Inference worker threads."),
    ("tre_queue_depth", "gauge", "Jobs waiting for a worker."),
    ("tre_queue_capacity", "gauge", "Capacity of the job queue."),
    ("tre_streams_open", "gauge", "Open WebSocket streams."),
    (
        "tre_connections_open",
        "gauge",
        "Open HTTP connections (a stream counts until its upgrade).",
    ),
    (
        "tre_connections_refused_total",
        "counter",
        "Connections refused over --max-connections.",
    ),
    (
        "tre_requests_total",
        "counter",
        "Requests and stream frames by endpoint and outcome.",
    ),
    (
        "tre_frames_dropped_total",
        "counter",
        "Stream frames skipped for a newer one.",
    ),
    (
        "tre_request_seconds",
        "histogram",
        "Latency from arrival to answer, of requests answered with a map.",
    ),
    (
        "tre_stage_seconds",
        "histogram",
        "Wall time of each pipeline stage.",
    ),
    (
        "tre_queue_wait_seconds",
        "histogram",
        "Time frames answered with a map waited for a worker.",
    ),
    (
        "tre_batch_size",
        "histogram",
        "Frames per worker run (every run, failed frames included).",
    ),
];

/// Every metric the service has always exposed keeps its name, type and help text (the ones
/// docs/service.md and the dashboards name). A labelled family is written once it has a
/// series.
#[test]
fn every_metric_keeps_its_name_type_and_help() {
    let m = Metrics::default();
    m.request("stream", "ok", Some(Duration::from_millis(5)));
    let mut timings = StageTimings::default();
    timings.add("depth", Duration::from_millis(4));
    m.frame(&timings, Duration::ZERO);
    let text = m.render(gauges());
    for (name, kind, help) in EVERY_METRIC {
        let lines = format!("# HELP {name} {help}\n# TYPE {name} {kind}\n");
        assert!(text.contains(&lines), "{name}:\n{text}");
    }
    for line in [
        "tre_ready 1\n",
        "tre_workers 2\n",
        "tre_queue_capacity 8\n",
        "tre_streams_open 0\n",
        "tre_connections_open 0\n",
        "tre_connections_refused_total 0\n",
        "tre_frames_dropped_total 0\n",
        "tre_queue_wait_seconds_count 1\n",
        "tre_batch_size_bucket{le=\"+Inf\"} 0\n",
        "tre_batch_size_count 0\n",
    ] {
        assert!(text.contains(line), "{line:?} missing:\n{text}");
    }
}

#[test]
fn counters_gauges_and_unlabelled_histograms_follow_the_events() {
    let m = Metrics::default();
    m.stream_open(true);
    m.stream_open(true);
    m.stream_open(false);
    m.connection_open(true);
    m.connection_refused();
    m.dropped();
    m.dropped();
    m.batch(1);
    m.batch(3);
    let mut timings = StageTimings::default();
    timings.add("normals", Duration::from_millis(4));
    m.frame(&timings, Duration::from_millis(2));
    let text = m.render(Gauges {
        ready: false,
        ..gauges()
    });
    for line in [
        "tre_ready 0\n",
        "tre_streams_open 1\n",
        "tre_connections_open 1\n",
        "tre_connections_refused_total 1\n",
        "tre_frames_dropped_total 2\n",
        "tre_batch_size_bucket{le=\"1\"} 1\n",
        "tre_batch_size_bucket{le=\"2\"} 1\n",
        "tre_batch_size_bucket{le=\"4\"} 2\n",
        "tre_batch_size_count 2\n",
        "tre_stage_seconds_bucket{stage=\"normals\",le=\"0.0025\"} 0\n",
        "tre_stage_seconds_bucket{stage=\"normals\",le=\"0.005\"} 1\n",
        "tre_stage_seconds_count{stage=\"normals\"} 1\n",
        "tre_queue_wait_seconds_bucket{le=\"0.0025\"} 1\n",
        "tre_queue_wait_seconds_count 1\n",
    ] {
        assert!(text.contains(line), "{line:?} missing:\n{text}");
    }
    assert_eq!(sample(&text, "tre_batch_size_sum"), 4.0);
}

#[test]
fn a_family_without_series_writes_nothing_and_then_its_first_series() {
    let m = Metrics::default();
    assert!(!m.render(gauges()).contains("tre_requests_total"));
    m.request("roughness", "too_large", None);
    let text = m.render(gauges());
    assert!(text.contains("# TYPE tre_requests_total counter\n"));
    assert!(text.contains("tre_requests_total{endpoint=\"roughness\",outcome=\"too_large\"} 1\n"));
    assert!(
        !text.contains("tre_request_seconds"),
        "refusals have no latency"
    );
}
