//! Reports for people: the text table of a run, the rows of a rate sweep with its knee, and the
//! side-by-side comparison of two runs' key numbers.

use std::collections::BTreeMap;
use std::fmt::Write as _;

use serde::{Deserialize, Serialize};

use super::stats::{fmt_rate, Percentiles, Report};

/// Where a sweep stops keeping up.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Knee {
    /// The first offered rate (per second) that broke the objective.
    pub rate_per_s: f64,
    /// Why: refusals, errors, a saturated client or a p99 above the objective.
    pub reasons: Vec<String>,
}

/// Open-loop runs at increasing rates.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct SweepReport {
    /// Objective on the p99 latency of results, milliseconds.
    pub slo_ms: f64,
    /// One run per rate, ascending.
    pub rows: Vec<Report>,
    /// The first rate with refusals, errors, a saturated client or p99 above the objective.
    pub knee: Option<Knee>,
    /// The highest rate below the knee (every row up to it clean and within the objective).
    pub sustained_rate_per_s: Option<f64>,
    /// Results per second achieved at that rate.
    pub sustained_ok_per_s: Option<f64>,
    /// The highest rate before the first refusal, error or saturated client, whatever its
    /// latency: the most the service took without turning anything away.
    #[serde(default)]
    pub clean_rate_per_s: Option<f64>,
    /// p99 of results at that rate, milliseconds.
    #[serde(default)]
    pub clean_p99_ms: Option<f64>,
    /// Every rate that was clean and had p99 within the objective (whether or not a lower
    /// rate broke it: near the service time, p99 is noisy).
    #[serde(default)]
    pub within_slo_rates_per_s: Vec<f64>,
    /// The first rate at which the service refused requests.
    pub first_refusal_rate_per_s: Option<f64>,
    /// The first rate whose p99 exceeded the objective.
    pub first_slo_breach_rate_per_s: Option<f64>,
}

impl SweepReport {
    /// The sweep over `rows` (ascending offered rates) against a p99 objective of `slo_ms`.
    pub fn new(rows: Vec<Report>, slo_ms: f64) -> Self {
        let rate = |r: &Report| r.run.offered_rate_per_s.unwrap_or(0.0);
        let knee_at = rows.iter().position(|r| !breaches(r, slo_ms).is_empty());
        let knee = knee_at.map(|i| Knee {
            rate_per_s: rate(&rows[i]),
            reasons: breaches(&rows[i], slo_ms),
        });
        let below = match knee_at {
            Some(0) => None,
            Some(i) => Some(&rows[i - 1]),
            None => rows.last(),
        };
        let dirty = |r: &Report| r.refused + r.errors + r.client_saturated > 0 || r.ok == 0;
        let clean = match rows.iter().position(dirty) {
            Some(0) => None,
            Some(i) => Some(&rows[i - 1]),
            None => rows.last(),
        };
        Self {
            slo_ms,
            knee,
            within_slo_rates_per_s: rows
                .iter()
                .filter(|r| breaches(r, slo_ms).is_empty())
                .map(rate)
                .collect(),
            clean_rate_per_s: clean.map(rate),
            clean_p99_ms: clean.map(|r| r.latency_ms.p99_ms),
            sustained_rate_per_s: below.map(rate),
            sustained_ok_per_s: below.map(|r| r.throughput_ok_per_s),
            first_refusal_rate_per_s: rows.iter().find(|r| r.refused > 0).map(rate),
            first_slo_breach_rate_per_s: rows
                .iter()
                .find(|r| r.latency_ms.p99_ms > slo_ms)
                .map(rate),
            rows,
        }
    }

    /// The sweep as pretty JSON.
    pub fn to_json(&self) -> String {
        serde_json::to_string_pretty(self).expect("a sweep always serialises; this is a bug")
    }
}

/// What keeps a run from meeting the objective (empty: it met it).
pub fn breaches(r: &Report, slo_ms: f64) -> Vec<String> {
    let mut why = Vec::new();
    if r.refused > 0 {
        why.push(format!("{} refused", r.refused));
    }
    if r.errors > 0 {
        why.push(format!("{} errors", r.errors));
    }
    if r.client_saturated > 0 {
        why.push(format!("{} client-saturated", r.client_saturated));
    }
    if r.ok == 0 {
        why.push("no result".into());
    } else if r.latency_ms.p99_ms > slo_ms {
        why.push(format!(
            "p99 {:.1} ms > {} ms",
            r.latency_ms.p99_ms,
            fmt_rate(slo_ms)
        ));
    }
    why
}

fn ms(v: f64, count: u64) -> String {
    if count == 0 {
        "-".into()
    } else {
        format!("{v:.1}")
    }
}

fn by_key(m: &BTreeMap<String, u64>) -> String {
    m.iter()
        .map(|(k, v)| format!("{k} {v}"))
        .collect::<Vec<_>>()
        .join(", ")
}

fn percentile_row(name: &str, p: &Percentiles) -> String {
    let c = p.count;
    format!(
        "{name:<10} {:>8} {:>8} {:>8} {:>8} {:>8} {:>8} {:>8}\n",
        ms(p.p50_ms, c),
        ms(p.p90_ms, c),
        ms(p.p99_ms, c),
        ms(p.p999_ms, c),
        ms(p.max_ms, c),
        ms(p.mean_ms, c),
        c
    )
}

/// The text table of one run.
pub fn text(r: &Report) -> String {
    let mut s = String::new();
    let offered = match r.run.offered_rate_per_s {
        Some(rate) => format!("open loop at {}/s", fmt_rate(rate)),
        None if r.run.connections == 1 => "closed loop, 1 client".into(),
        None => format!("closed loop, {} clients", r.run.connections),
    };
    let _ = writeln!(
        s,
        "{} {offered}, {:.1} s measured (+{:.1} s warm-up) → {}",
        r.run.protocol.as_str(),
        r.window_s,
        r.run.warmup_s,
        r.run.url
    );
    let _ = writeln!(s, "frames: {}", r.run.frames);
    let rate = r
        .run
        .offered_rate_per_s
        .map_or_else(|| "-".into(), |v| format!("{v:.2}/s"));
    let _ = writeln!(
        s,
        "requests {}   offered {rate}   achieved {:.2} ok/s   (last answer {:.2} s into the window)\n",
        r.requests, r.throughput_ok_per_s, r.answered_s
    );
    let share = |n: u64| {
        if r.requests == 0 {
            0.0
        } else {
            100.0 * n as f64 / r.requests as f64
        }
    };
    let _ = writeln!(s, "{:<17} {:>7} {:>7}", "outcome", "count", "share");
    let rows = [
        ("ok", r.ok, String::new()),
        ("refused", r.refused, by_key(&r.refused_by_code)),
        ("errors", r.errors, by_key(&r.errors_by_kind)),
        ("dropped", r.dropped, String::new()),
        ("client_saturated", r.client_saturated, String::new()),
    ];
    for (name, n, detail) in rows {
        let detail = if detail.is_empty() {
            detail
        } else {
            format!("   ({detail})")
        };
        let _ = writeln!(s, "{name:<17} {n:>7} {:>6.1}%{detail}", share(n));
    }
    let _ = writeln!(
        s,
        "\n{:<10} {:>8} {:>8} {:>8} {:>8} {:>8} {:>8} {:>8}",
        "latency ms", "p50", "p90", "p99", "p99.9", "max", "mean", "count"
    );
    s.push_str(&percentile_row("ok", &r.latency_ms));
    s.push_str(&percentile_row("refused", &r.refusal_latency_ms));
    s
}

/// Header of the sweep table.
pub fn sweep_header() -> String {
    format!(
        "{:>7} {:>7} {:>6} {:>7} {:>6} {:>7} {:>8} {:>8} {:>8} {:>8} {:>8} {:>9}",
        "rate/s",
        "ok/s",
        "ok",
        "refused",
        "errors",
        "dropped",
        "p50 ms",
        "p90 ms",
        "p99 ms",
        "p99.9 ms",
        "max ms",
        "refuse99"
    )
}

/// One row of the sweep table.
pub fn sweep_row(r: &Report) -> String {
    let p = &r.latency_ms;
    let c = p.count;
    format!(
        "{:>7} {:>7.2} {:>6} {:>7} {:>6} {:>7} {:>8} {:>8} {:>8} {:>8} {:>8} {:>9}",
        fmt_rate(r.run.offered_rate_per_s.unwrap_or(0.0)),
        r.throughput_ok_per_s,
        r.ok,
        r.refused,
        r.errors + r.client_saturated,
        r.dropped,
        ms(p.p50_ms, c),
        ms(p.p90_ms, c),
        ms(p.p99_ms, c),
        ms(p.p999_ms, c),
        ms(p.max_ms, c),
        ms(r.refusal_latency_ms.p99_ms, r.refusal_latency_ms.count),
    )
}

/// The sweep table with its knee and sustained rate.
pub fn sweep_text(sw: &SweepReport) -> String {
    let mut s = sweep_header();
    s.push('\n');
    for r in &sw.rows {
        s.push_str(&sweep_row(r));
        s.push('\n');
    }
    s.push_str(&sweep_summary(sw));
    s
}

/// The knee and sustained-rate lines of a sweep.
pub fn sweep_summary(sw: &SweepReport) -> String {
    let slo = fmt_rate(sw.slo_ms);
    let mut s = String::new();
    match &sw.knee {
        Some(k) => {
            let _ = writeln!(
                s,
                "knee: {}/s ({})",
                fmt_rate(k.rate_per_s),
                k.reasons.join("; ")
            );
        }
        None => {
            let _ = writeln!(s, "knee: not reached (every rate clean, p99 ≤ {slo} ms)");
        }
    }
    match (sw.sustained_rate_per_s, sw.sustained_ok_per_s) {
        (Some(rate), Some(ok)) => {
            let _ = writeln!(
                s,
                "sustained: {}/s offered, {ok:.2} ok/s, with p99 ≤ {slo} ms and no refusal or error",
                fmt_rate(rate)
            );
        }
        _ => {
            let _ = writeln!(s, "sustained: none of the rates met p99 ≤ {slo} ms cleanly");
        }
    }
    let within: Vec<String> = sw
        .within_slo_rates_per_s
        .iter()
        .map(|r| format!("{}/s", fmt_rate(*r)))
        .collect();
    let _ = writeln!(
        s,
        "rates with p99 ≤ {slo} ms and nothing refused: {}",
        if within.is_empty() {
            "none".into()
        } else {
            within.join(", ")
        }
    );
    if let (Some(rate), Some(p99)) = (sw.clean_rate_per_s, sw.clean_p99_ms) {
        let _ = writeln!(
            s,
            "clean (no refusal or error) up to: {}/s, p99 {p99:.1} ms",
            fmt_rate(rate)
        );
    }
    let at = |r: Option<f64>| r.map_or_else(|| "none".into(), |v| format!("{}/s", fmt_rate(v)));
    let _ = writeln!(
        s,
        "first refusals at: {}; first p99 > {slo} ms at: {}",
        at(sw.first_refusal_rate_per_s),
        at(sw.first_slo_breach_rate_per_s)
    );
    s
}

/// `new / old` as `1.23×`, or `-` when `old` is zero.
fn ratio(old: f64, new: f64) -> String {
    if old == 0.0 {
        if new == 0.0 {
            "=".into()
        } else {
            "-".into()
        }
    } else {
        format!("{:.2}×", new / old)
    }
}

/// Side-by-side key numbers of two runs with `new / old` ratios.
pub fn compare(old: &Report, new: &Report) -> String {
    let mut s = String::new();
    let _ = writeln!(s, "{:<18} {:>12} {:>12} {:>9}", "", "old", "new", "new/old");
    let _ = writeln!(s, "{:<18} {:>12} {:>12}", "run", old.label(), new.label());
    // Percentiles of no answers are absent (`-`), not 0.
    let of = |p: &Percentiles, v: fn(&Percentiles) -> f64| (p.count > 0).then(|| v(p));
    let latency =
        |name, v: fn(&Percentiles) -> f64| (name, of(&old.latency_ms, v), of(&new.latency_ms, v));
    let num_rows = [
        (
            "throughput ok/s",
            Some(old.throughput_ok_per_s),
            Some(new.throughput_ok_per_s),
        ),
        latency("p50 ms", |p| p.p50_ms),
        latency("p90 ms", |p| p.p90_ms),
        latency("p99 ms", |p| p.p99_ms),
        latency("p99.9 ms", |p| p.p999_ms),
        latency("max ms", |p| p.max_ms),
        (
            "refusal p99 ms",
            of(&old.refusal_latency_ms, |p| p.p99_ms),
            of(&new.refusal_latency_ms, |p| p.p99_ms),
        ),
    ];
    let cell = |v: Option<f64>| v.map_or_else(|| "-".to_owned(), |v| format!("{v:.2}"));
    for (name, o, n) in num_rows {
        let r = match (o, n) {
            (Some(o), Some(n)) => ratio(o, n),
            _ => "-".to_owned(),
        };
        let _ = writeln!(s, "{name:<18} {:>12} {:>12} {r:>9}", cell(o), cell(n));
    }
    let share = |n: u64, r: &Report| {
        if r.requests == 0 {
            0.0
        } else {
            n as f64 / r.requests as f64
        }
    };
    let count_rows = [
        ("requests", old.requests, new.requests),
        ("ok", old.ok, new.ok),
        ("refused", old.refused, new.refused),
        ("errors", old.errors, new.errors),
        ("dropped", old.dropped, new.dropped),
        (
            "client_saturated",
            old.client_saturated,
            new.client_saturated,
        ),
    ];
    for (name, o, n) in count_rows {
        let _ = writeln!(
            s,
            "{name:<18} {o:>12} {n:>12} {:>9}",
            ratio(share(o, old), share(n, new))
        );
    }
    s.push_str("(counts: ratio of their shares of the requests)\n");
    s
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;
    use crate::stats::{histogram, record, spectrum, RunInfo};
    use crate::Protocol;
    use std::time::Duration;

    /// A report with `ok` results at `ms` and `refused` refusals.
    pub(crate) fn report(rate: f64, ok: u64, ms: u64, refused: u64) -> Report {
        let mut h = histogram();
        for _ in 0..ok {
            record(&mut h, Duration::from_millis(ms));
        }
        Report {
            run: RunInfo {
                protocol: Protocol::Http,
                load: "open".into(),
                url: "http://127.0.0.1:1/v1/roughness".into(),
                frames: "synthetic".into(),
                offered_rate_per_s: Some(rate),
                connections: 1,
                max_in_flight: 256,
                warmup_s: 0.0,
                window_start_unix_s: 0.0,
            },
            window_s: 10.0,
            answered_s: 10.0,
            requests: ok + refused,
            ok,
            refused,
            dropped: 0,
            errors: 0,
            client_saturated: 0,
            refused_by_code: if refused > 0 {
                BTreeMap::from([("overloaded".to_string(), refused)])
            } else {
                BTreeMap::new()
            },
            errors_by_kind: BTreeMap::new(),
            throughput_ok_per_s: ok as f64 / 10.0,
            latency_ms: Percentiles::of(&h),
            refusal_latency_ms: Percentiles::default(),
            spectrum_ok: spectrum(&h),
            spectrum_refused: Vec::new(),
            samples: Vec::new(),
        }
    }

    #[test]
    fn the_knee_is_the_first_rate_with_refusals_or_a_slow_p99() {
        let rows = vec![
            report(4.0, 40, 100, 0),
            report(6.0, 60, 120, 0),
            report(8.0, 80, 200, 0),
            report(10.0, 80, 300, 20),
        ];
        let sw = SweepReport::new(rows, 150.0);
        let knee = sw.knee.clone().expect("a knee");
        assert_eq!(knee.rate_per_s, 8.0);
        assert!(knee.reasons[0].starts_with("p99 200"), "{:?}", knee.reasons);
        assert_eq!(sw.sustained_rate_per_s, Some(6.0));
        assert_eq!(sw.first_refusal_rate_per_s, Some(10.0));
        assert_eq!(sw.first_slo_breach_rate_per_s, Some(8.0));
        assert_eq!(sw.clean_rate_per_s, Some(8.0));
        assert_eq!(sw.within_slo_rates_per_s, [4.0, 6.0]);
        assert!(sw.clean_p99_ms.is_some_and(|p| (p - 200.0).abs() < 1.0));
        let text = sweep_text(&sw);
        assert!(text.contains("nothing refused: 4/s, 6/s"), "{text}");
        assert!(text.contains("knee: 8/s"), "{text}");
        assert!(text.contains("first refusals at: 10/s"), "{text}");
        let clean = SweepReport::new(vec![report(4.0, 40, 100, 0)], 150.0);
        assert_eq!((clean.knee, clean.sustained_rate_per_s), (None, Some(4.0)));
        let json = sw.to_json();
        let back: SweepReport = serde_json::from_str(&json).expect("parses");
        assert_eq!(back.knee, sw.knee);
        assert_eq!(back.rows.len(), 4);
    }

    #[test]
    fn the_text_table_names_every_outcome_and_percentile() {
        let r = report(10.0, 90, 120, 10);
        let t = text(&r);
        for needle in [
            "open loop at 10/s",
            "achieved 9.00 ok/s",
            "refused",
            "(overloaded 10)",
            "p99.9",
            "client_saturated",
        ] {
            assert!(t.contains(needle), "{needle:?} missing in\n{t}");
        }
    }

    #[test]
    fn compare_shows_ratios_of_the_key_numbers() {
        let old = report(10.0, 100, 100, 0);
        let new = report(10.0, 100, 200, 0);
        let c = compare(&old, &new);
        let p50 = c
            .lines()
            .find(|l| l.starts_with("p50 ms"))
            .expect("p50 row");
        assert!(p50.ends_with("2.00×"), "{p50}");
        let thr = c
            .lines()
            .find(|l| l.starts_with("throughput"))
            .expect("row");
        assert!(thr.ends_with("1.00×"), "{thr}");
        let errors = c.lines().find(|l| l.starts_with("errors")).expect("row");
        assert!(errors.ends_with('='), "{errors}");
        // No refusals in the new run: its refusal p99 is absent, not 0.
        let mut refusing = report(10.0, 100, 100, 5);
        refusing.refusal_latency_ms = Percentiles {
            count: 5,
            p99_ms: 3.0,
            ..Percentiles::default()
        };
        let c = compare(&refusing, &new);
        let refusal = c
            .lines()
            .find(|l| l.starts_with("refusal p99"))
            .expect("row");
        let cells: Vec<&str> = refusal.split_whitespace().collect();
        assert_eq!(cells[3..], ["3.00", "-", "-"], "{refusal}");
    }
}
