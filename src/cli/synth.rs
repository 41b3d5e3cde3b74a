//! `tre synth`: generate a synthetic terrain dataset (RougE-style) with exact ground truth.

use std::path::PathBuf;
use std::time::Instant;

use clap::Args;

use crate::roughness::noise::SensorPreset;
use crate::synth::imaging::ImageEffect;
use crate::synth::{
    content::Content,
    dataset::{generate, SynthConfig},
};

/// Generate a synthetic terrain dataset.
#[derive(Debug, Args)]
pub(crate) struct Synth {
    /// Output folder (created if missing).
    #[arg(long)]
    pub out: PathBuf,
    /// Number of scenes (9 views each by default).
    #[arg(long, default_value_t = 4)]
    pub scenes: u32,
    /// Dataset seed: the same seed gives the same bytes.
    #[arg(long, default_value_t = 0)]
    pub seed: u64,
    /// Image width, pixels.
    #[arg(long, default_value_t = 512)]
    pub width: usize,
    /// Image height, pixels.
    #[arg(long, default_value_t = 512)]
    pub height: usize,
    /// Horizontal field of view, degrees.
    #[arg(long, default_value_t = 60.0)]
    pub hfov_deg: f64,
    /// Views per scene, spread over ±60° of yaw.
    #[arg(long, default_value_t = 9)]
    pub views: u32,
    /// Draw camera height (0.4–1.2 m) and pitch (40–75°) per scene instead of 1 m and 60°.
    #[arg(long)]
    pub random_mounting: bool,
    /// Draw every frame's camera: pitch 0–85°, height 0.2–2.0 m, roll ±10°, horizontal field
    /// of view 45–110° and shape 4:3, 16:9 or 1242:375 (the width stays --width); overrides
    /// --random-mounting, --hfov-deg and --height.
    #[arg(long)]
    pub random_optics: bool,
    /// Share of scenes in the test split.
    #[arg(long, default_value_t = 0.2)]
    pub test_fraction: f64,
    /// Skip the PLY point clouds (they are the largest files).
    #[arg(long)]
    pub no_ply: bool,
    /// Depth sensor(s) of `depth_sensor.png`: kinect_v1, realsense_d435, azure_kinect, lidar or
    /// exact; a comma-separated list draws one per frame (docs/synth.md).
    #[arg(
        long,
        env = "TRE_SYNTH_SENSOR",
        value_delimiter = ',',
        default_value = "exact"
    )]
    pub sensor: Vec<SensorPreset>,
    /// Image-formation effects on rgb.png, each drawn per frame: exposure, white_balance,
    /// vignetting, defocus, motion_blur, noise, jpeg (comma-separated; leave one out to turn it
    /// off; none by default). Ranges in docs/synth.md.
    #[arg(long, env = "TRE_SYNTH_EFFECTS", value_delimiter = ',')]
    pub effects: Vec<ImageEffect>,
    /// What the scenes show: natural (the paper's six terrain categories), indoor (floors,
    /// walls, sills, cables, boxes, furniture, stairs), urban (road, sidewalk, curb, kerb ramp,
    /// drains, posts) or mixed (each scene draws one). Labels in docs/synth.md.
    #[arg(long, env = "TRE_SYNTH_CONTENT", default_value = "natural")]
    pub content: Content,
    /// Continue an interrupted run into the same --out with the same settings: complete
    /// frames are kept, the others written.
    #[arg(long, env = "TRE_SYNTH_RESUME")]
    pub resume: bool,
}

impl Synth {
    /// Generates the dataset and prints its size and speed.
    pub(crate) fn run(self) -> anyhow::Result<()> {
        let cfg = SynthConfig {
            out: self.out,
            scenes: self.scenes,
            seed: self.seed,
            size: (self.width, self.height),
            hfov_deg: self.hfov_deg,
            views: self.views,
            random_mounting: self.random_mounting,
            test_fraction: self.test_fraction,
            ply: !self.no_ply,
            sensors: self.sensor,
            effects: self.effects,
            content: self.content,
            random_optics: self.random_optics,
            resume: self.resume,
            ..SynthConfig::default()
        };
        let start = Instant::now();
        let m = generate(&cfg)?;
        let secs = start.elapsed().as_secs_f64();
        let frames = m.counts.0 + m.counts.1;
        println!(
            "{} scenes, {frames} frames ({} train, {} test) in {secs:.1} s ({:.2} frames/s) → {}",
            m.scenes.len(),
            m.counts.0,
            m.counts.1,
            frames as f64 / secs,
            cfg.out.display()
        );
        Ok(())
    }
}
