//! `tre loadtest`: open- or closed-loop load on a running `tre serve` over HTTP or WebSocket,
//! with a text report, JSON, an SVG latency plot, a comparison with an earlier run and rate
//! sweeps that find the knee. The options are [`LoadtestArgs`].

use anyhow::Context;
use clap::Args;

use crate::loadtest::report::{self, SweepReport};
use crate::loadtest::{run, svg, sweep, LoadtestArgs};

/// Load a running `tre serve` and report throughput and latency.
#[derive(Debug, Args)]
pub(crate) struct Loadtest {
    /// The target, the frames, the load and the reports.
    #[command(flatten)]
    pub args: LoadtestArgs,
}

impl Loadtest {
    /// Runs the load, prints the report and writes the files asked for.
    pub(crate) fn run(self) -> anyhow::Result<()> {
        let args = &self.args;
        args.check_outputs()?;
        let cfg = args.config()?;
        let old = args.compared()?;
        let runtime = tokio::runtime::Builder::new_multi_thread()
            .thread_name("tre-loadtest")
            .enable_all()
            .build()
            .context("starting the async runtime")?;
        if args.sweep.is_empty() {
            let r = runtime.block_on(run(&cfg))?;
            print!("{}", report::text(&r));
            if let (Some(old), Some(path)) = (&old, &args.compare) {
                println!("\ncompared with {}:", path.display());
                print!("{}", report::compare(old, &r));
            }
            args.write(&r.to_json(), || svg::plot_run(&r))?;
            no_result_is_a_failure(r.ok, r.requests)
        } else {
            // The header comes with the first row: a sweep refused before it runs prints none.
            let mut header = Some(report::sweep_header());
            let sw: SweepReport = runtime.block_on(sweep(&cfg, &args.sweep, args.slo_ms, |r| {
                if let Some(h) = header.take() {
                    println!("{h}");
                }
                println!("{}", report::sweep_row(r));
            }))?;
            print!("{}", report::sweep_summary(&sw));
            args.write(&sw.to_json(), || svg::plot_sweep(&sw))?;
            let (ok, requests) = sw
                .rows
                .iter()
                .fold((0, 0), |(o, n), r| (o + r.ok, n + r.requests));
            no_result_is_a_failure(ok, requests)
        }
    }
}

/// A load test in which no request got a roughness map measured nothing about the service: it
/// fails (after its report is printed and written), so that a script does not take it for a
/// result.
fn no_result_is_a_failure(ok: u64, requests: u64) -> anyhow::Result<()> {
    if ok == 0 {
        anyhow::bail!(
            "none of the {requests} requests got a roughness map: is the target a running tre \
             serve (see the errors above)?"
        );
    }
    Ok(())
}
