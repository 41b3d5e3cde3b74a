//! `tre eval`: scores the pipeline (any mode and switches, or the end-to-end baseline) on a
//! split of a `tre synth` dataset against annotation spec v1: roughness RMSE, B-RMSE, F-RMSE;
//! normal angle errors; depth errors in rgb mode; mean time per stage. `--tables` runs every
//! row of the paper's Tables II, IV and V and prints them as markdown.

use std::path::{Path, PathBuf};

use anyhow::Context;
use clap::Args;
use tre_eval::synthetic::{self, SplitReport};
use tre_eval::{real, tables, EvalArgs};

use crate::io::paths::{refuse_overwriting, write_text};
use crate::pipeline::PipelineConfig;

/// Score a method on a synthetic dataset's split, or every mode on real RGB-D frames.
#[derive(Debug, Args)]
pub(crate) struct Eval {
    /// The data, the split, the pipeline and the outputs.
    #[command(flatten)]
    pub args: EvalArgs,
}

impl Eval {
    /// Scores every frame of the split and prints the metrics (and the tables), or runs the
    /// real-frame benchmark.
    pub(crate) fn run(self) -> anyhow::Result<()> {
        let a = &self.args;
        if !a.real.is_empty() {
            return run_real(a, &a.real);
        }
        let data = a.data.clone().context("--data or --real is needed")?;
        if let Some(json) = &a.json {
            // The dataset's manifest and its scene folders are inputs; a report beside them
            // is fine.
            let inputs = synthetic::dataset_inputs(&data);
            let inputs: Vec<&Path> = inputs.iter().map(PathBuf::as_path).collect();
            refuse_overwriting(&[json], &inputs)?;
        }
        let dirs = synthetic::frame_dirs(&data, &a.split, a.limit)?;
        let specs = a.synthetic_rows()?;
        let configs: Vec<PipelineConfig> = specs.iter().map(|s| s.cfg).collect();
        let mut pipeline = a.stages.pipeline(&configs)?;
        let rows = synthetic::score_split(&mut pipeline, &dirs, &specs, a.depth_source)?;
        println!(
            "{}, split {}, {} frames\n",
            data.display(),
            a.split,
            dirs.len()
        );
        if a.tables {
            println!("{}", tables::markdown(&rows));
        } else {
            rows.iter()
                .for_each(|r| print!("{}", synthetic::row_text(r)));
        }
        if let Some(path) = &a.json {
            let report = SplitReport {
                data: &data,
                split: &a.split,
                frames: dirs.len(),
                rows: &rows,
            };
            write_text(path, &serde_json::to_string_pretty(&report)?)?;
        }
        Ok(())
    }
}

/// The real-frame benchmark (`--real`): markdown on stdout, `--json`, `--sheets`.
fn run_real(a: &EvalArgs, dirs: &[PathBuf]) -> anyhow::Result<()> {
    if let Some(json) = &a.json {
        let inputs: Vec<&Path> = dirs.iter().map(PathBuf::as_path).collect();
        refuse_overwriting(&[json], &inputs)?;
    }
    let frames = a.real_frames(dirs)?;
    if let Some(path) = &a.regions {
        let file = real::RegionFile::read(path)?;
        let rows = a.region_rows();
        let configs: Vec<PipelineConfig> = rows.iter().map(|(_, c)| *c).collect();
        let mut pipeline = a.stages.pipeline(&configs)?;
        let report = real::score_regions(&frames, &file, &rows, &mut pipeline, &a.sensor)?;
        println!("{}", real::regions_markdown(&report));
        if let Some(path) = &a.json {
            write_text(path, &serde_json::to_string_pretty(&report)?)?;
        }
        return Ok(());
    }
    let floors = match &a.floors {
        Some(path) => real::read_floors(path)?,
        None => real::Floors::new(),
    };
    let rows = a.real_rows();
    let configs: Vec<PipelineConfig> = rows.iter().map(|(_, c)| *c).collect();
    let mut pipeline = a.stages.pipeline(&configs)?;
    if let Some(sheets) = &a.sheets {
        std::fs::create_dir_all(sheets)
            .with_context(|| format!("creating {}", sheets.display()))?;
    }
    let sheets = a.sheets.as_deref();
    let split = a.real_splits.as_ref().map(|_| a.split.as_str());
    let mut report = real::run_benchmark(
        (dirs, split),
        (&frames, a.reference),
        &floors,
        &rows,
        &mut pipeline,
        &a.sensor,
        |f, l, maps| match sheets {
            Some(sheets) => real::write_sheet(sheets, f, l, &rows, maps),
            None => Ok(()),
        },
    )?;
    report.mounting_ignored = a.no_mounting;
    println!("{}", real::markdown(&report));
    if let Some(path) = &a.json {
        write_text(path, &serde_json::to_string_pretty(&report)?)?;
    }
    Ok(())
}
