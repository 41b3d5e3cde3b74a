//! `tre eval`: scores roughness and normals on the test split of a `tre synth` dataset. For now
//! the `geometric` mode (no networks): LS normals and window centroids on the true depth,
//! roughness `|n·(p − c)|` (Eq. 1), against annotation spec v1.

use std::path::{Path, PathBuf};

use anyhow::{bail, Context};
use clap::{Args, ValueEnum};

use crate::geometry::{local_planes, Grid, Neighbourhood, Vec3, INVALID_POINT};
use crate::io;
use crate::roughness::{NormalAccumulator, RoughnessAccumulator};
use crate::synth::dataset::Manifest;

/// Input modes (the paper's Table IV rows); only `geometric` runs without models.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum Mode {
    /// Depth only, no networks: LS normals and window centroids.
    Geometric,
}

/// Score a method on a synthetic dataset's test split.
#[derive(Debug, Args)]
pub struct Eval {
    /// Dataset folder written by `tre synth` (holds dataset.json).
    #[arg(long)]
    pub data: PathBuf,
    /// Input mode.
    #[arg(long, value_enum, default_value = "geometric")]
    pub mode: Mode,
    /// Split to score.
    #[arg(long, default_value = "test")]
    pub split: String,
}

impl Eval {
    /// Scores every frame of the split and prints the metrics.
    pub fn run(self) -> anyhow::Result<()> {
        let text = std::fs::read_to_string(self.data.join("dataset.json"))
            .with_context(|| format!("reading {}/dataset.json", self.data.display()))?;
        let manifest: Manifest = serde_json::from_str(&text).context("parsing dataset.json")?;
        let dirs: Vec<PathBuf> = manifest
            .scenes
            .iter()
            .filter(|s| s.split == self.split)
            .flat_map(|s| s.frames.iter().map(|f| self.data.join(&f.dir)))
            .collect();
        if dirs.is_empty() {
            bail!("no frames in split {:?}", self.split);
        }
        let (mut rough, mut normals) = (
            RoughnessAccumulator::default(),
            NormalAccumulator::default(),
        );
        for dir in &dirs {
            score_frame(dir, &mut rough, &mut normals)
                .with_context(|| format!("frame {}", dir.display()))?;
        }
        let (r, n) = (rough.finish(), normals.finish());
        println!(
            "mode {:?}, split {}, {} frames",
            self.mode,
            self.split,
            dirs.len()
        );
        println!("roughness  RMSE {:.3} cm  B-RMSE {:.3} cm  F-RMSE {:.3} cm  ({} px, {} without prediction)", r.rmse_cm, r.b_rmse_cm, r.f_rmse_cm, r.pixels, r.missing);
        println!(
            "normals    mean {:.2}°  median {:.2}°  <11.25° {:.1}%  <22.5° {:.1}%  <30° {:.1}%",
            n.mean_deg, n.median_deg, n.under_11_25_pct, n.under_22_5_pct, n.under_30_pct
        );
        Ok(())
    }
}

/// Geometric roughness and LS normals of one frame, added to the accumulators.
fn score_frame(
    dir: &Path,
    rough: &mut RoughnessAccumulator,
    normals: &mut NormalAccumulator,
) -> anyhow::Result<()> {
    let (cam, k) = io::read_camera(&dir.join("camera.json"))?;
    let depth = io::read_depth(&dir.join("depth.png"), cam.depth_scale.unwrap_or(1000.0))?;
    let points = k.back_project_map(&depth);
    let planes = local_planes(&points, k.fx_px, &Neighbourhood::default());
    let pred = Grid::par_from_fn(depth.width(), depth.height(), |x, y| {
        planes.normal[(x, y)]
            .dot(&(points[(x, y)] - planes.centroid[(x, y)]))
            .abs()
    });
    let gt = io::decode_roughness_png16(&io::read_image(&dir.join("roughness.png"))?);
    let boundary = io::read_labels(&dir.join("boundary.png"))?.map(|&b| b > 0);
    rough.add(&pred, &gt, &boundary)?;
    let gt_normals = io::read_normals(&dir.join("normals.npy"))?;
    let pred_normals = planes
        .normal
        .map(|n: &Vec3| if n.x.is_finite() { *n } else { INVALID_POINT });
    normals.add(&pred_normals, &gt_normals)?;
    Ok(())
}
