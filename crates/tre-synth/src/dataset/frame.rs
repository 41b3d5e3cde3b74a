//! The frames of one scene: each view rendered, annotated and written into its own folder (in
//! parallel), or kept from an interrupted run; the scene's manifest entry and contact-sheet rows.

use std::path::Path;

use image::RgbImage;
use rayon::prelude::*;

use super::manifest::{FrameEntry, SceneEntry};
use super::scene::{draw, sample_scene, scene_terrain, scene_views, view_conditions, view_sensor};
use super::sheet::tiles;
use super::writer::{annotate_frame, write_frame, FrameError, FrameOut};
use super::{SynthConfig, SynthError};
use crate::imaging::Imaging;
use crate::render::{render, Scene, View};
use tre_io::IoError;

/// The folder of view `v` of scene `s`, relative to the dataset root.
fn frame_dir(s: u32, v: u32) -> String {
    format!("scene_{s:05}/view_{v}")
}

/// Whether view `v` of scene `s` gives a row of the dataset's contact sheet.
fn in_sheet(s: u32, v: u32) -> bool {
    s < 2 && v.is_multiple_of(4)
}

/// Renders, annotates and writes the frames of scene `s` (those a resumed run lacks); returns
/// its manifest entry and its contact-sheet rows.
pub(super) fn generate_scene(
    cfg: &SynthConfig,
    s: u32,
) -> Result<(SceneEntry, Vec<RgbImage>), SynthError> {
    let views = scene_views(cfg, s);
    let terrain = scene_terrain(cfg, s, &views);
    let categories = (terrain.regions.iter().map(|r| r.category))
        .chain(terrain.objects.iter().map(|o| o.category))
        .collect();
    // A resumed run keeps complete frames (their folders exist: each is renamed into place
    // once written); the scene is sampled only if a frame is missing or gives a sheet row.
    let kept: Vec<bool> = (0..cfg.views)
        .map(|v| cfg.resume && cfg.out.join(frame_dir(s, v)).is_dir())
        .collect();
    let needed = (0..cfg.views).any(|v| !kept[v as usize] || in_sheet(s, v));
    let scene = needed.then(|| sample_scene(cfg, &views, terrain));
    // Views render, annotate and encode in parallel (each also parallel inside).
    let done: Vec<(FrameEntry, Option<RgbImage>)> = views
        .par_iter()
        .enumerate()
        .map(|(v, view)| {
            let v = v as u32;
            let job = FrameJob { cfg, s, v, view };
            let tiles = match &scene {
                Some(scene) if !kept[v as usize] => Some(job.write(scene)?),
                Some(scene) if in_sheet(s, v) => Some(job.preview(scene)?),
                _ => None,
            };
            Ok((job.entry(), tiles))
        })
        .collect::<Result<_, SynthError>>()?;
    let previews = done
        .iter()
        .filter(|(e, _)| in_sheet(s, e.view))
        .filter_map(|(_, t)| t.clone())
        .collect();
    let frames = done.into_iter().map(|(e, _)| e).collect();
    let m = views[0].mounting;
    let split = if draw(cfg.seed, s, 4) < cfg.test_fraction {
        "test"
    } else {
        "train"
    };
    let entry = SceneEntry {
        scene: s,
        split: split.into(),
        height_m: m.height_m,
        pitch_deg: m.pitch_rad.to_degrees(),
        content: cfg.content.family(cfg.seed, u64::from(s)),
        categories,
        frames,
    };
    Ok((entry, previews))
}

/// One frame of the dataset: view `v` of scene `s`.
struct FrameJob<'a> {
    cfg: &'a SynthConfig,
    s: u32,
    v: u32,
    view: &'a View,
}

impl FrameJob<'_> {
    fn entry(&self) -> FrameEntry {
        let cond = view_conditions(self.cfg, self.s, self.v);
        FrameEntry {
            dir: frame_dir(self.s, self.v),
            view: self.v,
            yaw_deg: self.view.yaw_rad.to_degrees(),
            lighting: cond.lighting,
            weather: cond.weather,
            sensor: view_sensor(self.cfg, self.s, self.v).0,
        }
    }

    fn error(&self, e: FrameError) -> SynthError {
        match e {
            FrameError::Io(e) => SynthError::Io(e),
            FrameError::Annotate(source) => SynthError::Annotate {
                scene: self.s,
                view: self.v,
                source,
            },
        }
    }

    /// Renders and writes the frame into `view_V.partial`, then renames that folder to
    /// `view_V` (replacing an older one): a frame folder is complete or absent. Returns its
    /// contact-sheet row.
    fn write(&self, scene: &Scene) -> Result<RgbImage, SynthError> {
        let (cfg, s, v) = (self.cfg, self.s, self.v);
        let cond = view_conditions(cfg, s, v);
        let frame = render(scene, self.view, &cond);
        let sensor = view_sensor(cfg, s, v);
        let dir = cfg.out.join(frame_dir(s, v));
        let partial = dir.with_extension("partial");
        remove_dir_if_there(&partial)?;
        let out = FrameOut {
            dir: &partial,
            view: self.view,
            cond: &cond,
            sensor,
            imaging: Imaging::draw(&cfg.effects, sensor.1 ^ 0x1A6E),
            ply: cfg.ply,
        };
        let tiles = write_frame(&out, &frame).map_err(|e| self.error(e))?;
        remove_dir_if_there(&dir)?;
        std::fs::rename(&partial, &dir).map_err(IoError::from)?;
        Ok(tiles)
    }

    /// The contact-sheet row of a kept frame, rendered and annotated again (not written).
    fn preview(&self, scene: &Scene) -> Result<RgbImage, SynthError> {
        let cond = view_conditions(self.cfg, self.s, self.v);
        let f = render(scene, self.view, &cond);
        let ann = annotate_frame(&f, &self.view.intrinsics).map_err(|e| self.error(e))?;
        Ok(tiles(&f, &ann.roughness_m))
    }
}

fn remove_dir_if_there(dir: &Path) -> Result<(), IoError> {
    match std::fs::remove_dir_all(dir) {
        Err(e) if e.kind() != std::io::ErrorKind::NotFound => Err(e.into()),
        _ => Ok(()),
    }
}
