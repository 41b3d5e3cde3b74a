//! `tre annotate`: roughness ground truth for one depth frame (annotation spec v1), written as
//! a 16-bit PNG, float `.npy`, boundary mask, edge weights, segment ids and a preview.

use std::path::{Path, PathBuf};

use anyhow::{bail, Context};
use clap::Args;

use crate::io;
use crate::roughness::annotate::{annotate, AnnotateConfig, AnnotateInput, Annotation};

/// Annotate a depth frame with roughness.
#[derive(Debug, Args)]
pub(crate) struct Annotate {
    /// Depth: 16-bit grey PNG (see --depth-scale) or float .npy in metres; 0 = no data.
    #[arg(long)]
    pub depth: PathBuf,
    /// Camera JSON with fx, fy, cx, cy (pixels) and optionally width, height, depth_scale.
    #[arg(long)]
    pub camera: PathBuf,
    /// Depth PNG units per metre (1000: millimetres, 5000: TUM); default: the camera JSON's
    /// depth_scale, else 1000.
    #[arg(long, env = "TRE_DEPTH_SCALE")]
    pub depth_scale: Option<f64>,
    /// Optional normals, (H, W, 3) float .npy in the camera frame; LS normals otherwise.
    #[arg(long)]
    pub normals: Option<PathBuf>,
    /// Optional semantic labels (grey PNG or .npy; 0 = void); one label for all otherwise.
    #[arg(long)]
    pub labels: Option<PathBuf>,
    /// Output folder (created if missing).
    #[arg(long, short)]
    pub out: PathBuf,
    /// The spec's settings.
    #[command(flatten)]
    pub spec: AnnotateConfig,
    /// Top of the preview's colour scale, centimetres.
    #[arg(long, default_value_t = 5.0)]
    pub preview_max_cm: f64,
}

impl Annotate {
    /// Reads the inputs, annotates and writes every output.
    pub(crate) fn run(self) -> anyhow::Result<()> {
        self.check_outputs()?;
        let cfg = self.spec.checked()?;
        if !(self.preview_max_cm.is_finite() && self.preview_max_cm > 0.0) {
            bail!(
                "--preview-max-cm must be positive, got {}",
                self.preview_max_cm
            );
        }
        let (cam, k) = io::read_camera(&self.camera)?;
        let scale = self.depth_scale.or(cam.depth_scale).unwrap_or(1000.0);
        if !(scale.is_finite() && scale > 0.0) {
            bail!("--depth-scale must be positive, got {scale}");
        }
        let depth = io::read_depth(&self.depth, scale)?;
        if let Err(why) = cam.check_size(depth.size()) {
            bail!(
                "camera {} and depth {}: {why}",
                self.camera.display(),
                self.depth.display()
            );
        }
        k.check_for(depth.width(), depth.height())
            .with_context(|| format!("camera {}", self.camera.display()))?;
        let normals = self.normals.as_deref().map(io::read_normals).transpose()?;
        let labels = self.labels.as_deref().map(io::read_labels).transpose()?;
        let input = AnnotateInput {
            depth_m: &depth,
            intrinsics: &k,
            normals: normals.as_ref(),
            labels: labels.as_ref(),
        };
        let ann = annotate(&input, &cfg)
            .with_context(|| format!("annotating {}", self.depth.display()))?;
        self.write(&ann)?;
        print_summary(&ann);
        Ok(())
    }

    /// Refuses, before any work, an output folder that holds an input: its outputs would mix
    /// with the data there (a `tre synth` view's ground truth has the same file names), and any
    /// output that would replace an input lies in it.
    fn check_outputs(&self) -> anyhow::Result<()> {
        let inputs = [
            Some(&self.depth),
            Some(&self.camera),
            self.normals.as_ref(),
            self.labels.as_ref(),
        ];
        let out = crate::io::paths::resolved(&self.out);
        for input in inputs.into_iter().flatten() {
            if crate::io::paths::resolved(input).parent() == Some(out.as_path()) {
                bail!(
                    "--out {} holds the input {}: write the annotation to a folder of its own",
                    self.out.display(),
                    input.display()
                );
            }
        }
        Ok(())
    }

    fn write(&self, ann: &Annotation) -> anyhow::Result<()> {
        let title = format!("roughness, annotation spec v1: {}", file_name(&self.depth));
        let max_m = self.preview_max_cm / 100.0;
        Ok(io::outputs::write_annotation(
            &self.out, ann, max_m, &title,
        )?)
    }
}

/// Prints pixel counts and roughness quantiles.
fn print_summary(ann: &Annotation) {
    let r = crate::roughness::metrics::finite_sorted(&ann.roughness_m);
    let q = |f: f64| {
        r.get(((r.len() as f64 - 1.0) * f).round() as usize)
            .copied()
            .unwrap_or(f64::NAN)
            * 100.0
    };
    let boundary = ann.boundary.as_slice().iter().filter(|b| **b).count();
    let segments = ann.segments.as_slice().iter().max().copied().unwrap_or(0);
    println!(
        "valid {} px, boundary {boundary} px, segments {segments}; roughness cm: median {:.3}, p90 {:.3}, p99 {:.3}, max {:.3}",
        r.len(),
        q(0.5),
        q(0.9),
        q(0.99),
        q(1.0)
    );
}

/// The last component of `path`, for titles.
pub(super) fn file_name(path: &Path) -> String {
    path.file_name().map_or_else(
        || path.display().to_string(),
        |n| n.to_string_lossy().into_owned(),
    )
}
