//! The wall-clock bounds of the load tester and of the service's refusals, which `cargo test`
//! leaves out because they only hold on a quiet machine (the load-test tests in
//! `tests/it/loadtest/` assert what holds under any load): against the fake one-at-a-time
//! service of those tests, a closed loop's p99 with one 500 ms stall (under 100 ms: the stall is
//! one sample among hundreds), the window of 6 closed-loop requests of 20 ms (under 0.5 s), and
//! a sweep against a 50 ms objective (20/s meets it, 300/s is the knee); against the real
//! `tre serve` with one worker and a queue of 1 at 40/s, the refusals' p99 (under 50 ms).
//!
//! `cargo bench --bench loadtest` prints each measure beside its bound and exits with status 1
//! when one is over. Run it with nothing else loading the machine; the run takes about 15 s.
#![allow(missing_docs)]

#[path = "../tests/it/common/mod.rs"]
mod common;
#[path = "../tests/it/loadtest/fake.rs"]
mod fake;

use std::time::Duration;

use fake::{block_on, cfg, frames, ok, over_one_worker, Fake};
use tre::loadtest::{report, run_on, Load, LoadConfig, Target};

/// One measure against its bound.
struct Measure {
    what: &'static str,
    value: f64,
    unit: &'static str,
    /// The largest value that passes, or `None` for a measure shown beside the others.
    bound: Option<f64>,
}

impl Measure {
    fn over(&self) -> bool {
        self.bound.is_some_and(|b| !(self.value < b))
    }
}

/// A closed loop against the fake with one 500 ms stall, beside the open loop at 100/s.
fn stall(out: &mut Vec<Measure>) {
    let fake = || Fake {
        service: Duration::from_millis(5),
        stall: Some((Duration::from_millis(700), Duration::from_millis(500))),
        answer: ok,
    };
    let run =
        |load| block_on(run_on(&cfg(load), &Target::at(fake().start()), &frames())).expect("runs");
    let open = run(Load::Open { rate_per_s: 100.0 });
    let closed = run(Load::Closed);
    out.push(Measure {
        what: "fake with a 500 ms stall, open loop at 100/s: p99",
        value: open.latency_ms.p99_ms,
        unit: "ms",
        bound: None,
    });
    out.push(Measure {
        what: "fake with a 500 ms stall, closed loop: p99",
        value: closed.latency_ms.p99_ms,
        unit: "ms",
        bound: Some(100.0),
    });
}

/// The window of 6 closed-loop requests of 20 ms on 2 connections, without warm-up.
fn window(out: &mut Vec<Measure>) {
    let addr = Fake::steady(20, ok);
    let c = LoadConfig {
        connections: 2,
        requests: Some(6),
        duration: None,
        warmup: Duration::ZERO,
        ..cfg(Load::Closed)
    };
    let r = block_on(run_on(&c, &Target::at(addr), &frames())).expect("runs");
    out.push(Measure {
        what: "6 closed-loop requests of 20 ms: window",
        value: r.window_s * 1e3,
        unit: "ms",
        bound: Some(500.0),
    });
}

/// A sweep of 20/s and 300/s against a 10 ms fake and a 50 ms objective.
fn sweep(out: &mut Vec<Measure>) {
    let addr = Fake::steady(10, ok);
    let c = LoadConfig {
        url: format!("http://localhost:{}", addr.port()),
        duration: Some(Duration::from_millis(600)),
        ..cfg(Load::Closed)
    };
    let sw = block_on(tre::loadtest::sweep(&c, &[300.0, 20.0], 50.0, |_| {})).expect("runs");
    println!("{}", report::sweep_text(&sw));
    out.push(Measure {
        what: "sweep of a 10 ms fake: p99 at 20/s (objective)",
        value: sw.rows[0].latency_ms.p99_ms,
        unit: "ms",
        bound: Some(50.0),
    });
    out.push(Measure {
        what: "sweep of a 10 ms fake: knee (300/s expected)",
        value: sw.knee.as_ref().map_or(f64::NAN, |k| k.rate_per_s),
        unit: "/s",
        bound: None,
    });
}

/// The real service, one worker and a queue of 1, at 40/s for 3 s: refusals against results.
fn refusals(out: &mut Vec<Measure>) {
    let server = common::Server::start(&["--workers", "1", "--queue", "1"]);
    let r = over_one_worker(&server.url());
    println!("{}", report::text(&r));
    out.push(Measure {
        what: "tre serve, 1 worker, queue 1, 40/s: refusals' p99",
        value: r.refusal_latency_ms.p99_ms,
        unit: "ms",
        bound: Some(50.0),
    });
    out.push(Measure {
        what: "tre serve, 1 worker, queue 1, 40/s: results' p50",
        value: r.latency_ms.p50_ms,
        unit: "ms",
        bound: None,
    });
}

fn main() {
    // `cargo test --benches` runs bench targets without `--bench`: nothing to measure then.
    if !std::env::args().any(|a| a == "--bench") {
        println!("loadtest: wall-clock bounds, measured by `cargo bench --bench loadtest`");
        return;
    }
    let mut measures = Vec::new();
    stall(&mut measures);
    window(&mut measures);
    sweep(&mut measures);
    refusals(&mut measures);
    println!();
    for m in &measures {
        let verdict = match m.bound {
            Some(b) if m.over() => format!("OVER its bound of {b} {}", m.unit),
            Some(b) => format!("under {b} {}", m.unit),
            None => String::new(),
        };
        println!("{:<56} {:>9.1} {:<3} {verdict}", m.what, m.value, m.unit);
    }
    if measures.iter().any(Measure::over) {
        std::process::exit(1);
    }
}
