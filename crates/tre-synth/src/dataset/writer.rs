//! The files of one frame: `camera.json`, the images, the sensor depth, the normals, the spec's
//! maps and the point cloud.

use std::path::Path;

use image::{DynamicImage, RgbImage};

use super::manifest::{FrameCamera, SensorMeta};
use super::sheet::tiles;
use crate::appearance::Conditions;
use crate::imaging::Imaging;
use crate::render::{RenderedFrame, View};
use crate::sensor::{simulate, SensorInput, SensorModel};
use tre_core::roughness::noise::SensorPreset;
use tre_core::roughness::{
    annotate::{annotate, AnnotateConfig, AnnotateInput},
    RoughnessError,
};
use tre_io::{self as io, IoError};

/// Spec v1 on a rendered frame's exact depth, normals and labels.
pub(super) fn annotate_frame(
    f: &RenderedFrame,
    k: &tre_core::geometry::Intrinsics,
) -> Result<tre_core::roughness::annotate::Annotation, FrameError> {
    let input = AnnotateInput {
        depth_m: &f.depth_m,
        intrinsics: k,
        normals: Some(&f.normals_cam),
        labels: Some(&f.labels),
    };
    annotate(&input, &AnnotateConfig::default()).map_err(FrameError::Annotate)
}

/// Why a frame could not be written.
pub(super) enum FrameError {
    Io(IoError),
    Annotate(RoughnessError),
}

impl From<IoError> for FrameError {
    fn from(e: IoError) -> Self {
        FrameError::Io(e)
    }
}

/// Where and how one frame is written.
pub(super) struct FrameOut<'a> {
    /// The frame's folder.
    pub dir: &'a Path,
    /// Its camera.
    pub view: &'a View,
    /// Its lighting and weather.
    pub cond: &'a Conditions,
    /// Its depth sensor and noise seed.
    pub sensor: (SensorPreset, u64),
    /// The image formation of `rgb.png`.
    pub imaging: Imaging,
    /// Whether to write the point cloud.
    pub ply: bool,
}

/// Writes every file of one frame; returns the contact-sheet tiles (rgb, depth, normals,
/// labels, roughness).
pub(super) fn write_frame(out: &FrameOut<'_>, f: &RenderedFrame) -> Result<RgbImage, FrameError> {
    let (dir, view, cond) = (out.dir, out.view, out.cond);
    std::fs::create_dir_all(dir).map_err(IoError::from)?;
    let k = &view.intrinsics;
    let model = SensorModel::preset(out.sensor.0);
    let cam = FrameCamera {
        fx: k.fx_px,
        fy: k.fy_px,
        cx: k.cx_px,
        cy: k.cy_px,
        width: view.width,
        height: view.height,
        depth_scale: 1000.0,
        pitch_deg: view.mounting.pitch_rad.to_degrees(),
        height_m: view.mounting.height_m,
        yaw_deg: view.yaw_rad.to_degrees(),
        roll_deg: view.roll_rad.to_degrees(),
        conditions: *cond,
        sensor: out.sensor.0,
        sensor_model: SensorMeta {
            seed: out.sensor.1,
            model,
        },
        imaging: out.imaging.clone(),
    };
    let json =
        serde_json::to_string_pretty(&cam).map_err(|e| IoError::from(std::io::Error::from(e)))?;
    std::fs::write(dir.join("camera.json"), json).map_err(IoError::from)?;
    let rgb = out.imaging.apply(&f.rgb);
    io::save(&dir.join("rgb.png"), &DynamicImage::ImageRgb8(rgb.clone()))?;
    io::save(
        &dir.join("depth.png"),
        &DynamicImage::ImageLuma16(io::depth_png16(&f.depth_m)),
    )?;
    write_sensor_depth(dir, f, k, &model, out.sensor.1)?;
    io::write_normals_npy(&dir.join("normals.npy"), &f.normals_cam)?;
    let labels = f.labels.map(|&l| l as u8);
    io::save(
        &dir.join("labels.png"),
        &DynamicImage::ImageLuma8(io::gray8(&labels)),
    )?;
    let ann = annotate_frame(f, k)?;
    io::save(
        &dir.join("roughness.png"),
        &DynamicImage::ImageLumaA16(io::roughness_png16(&ann.roughness_m)),
    )?;
    io::write_mask_png(&dir.join("boundary.png"), &ann.boundary)?;
    io::save(
        &dir.join("edge_weight.png"),
        &DynamicImage::ImageLuma16(io::metres_png16(&ann.edge_weight_m)),
    )?;
    if out.ply {
        io::write_ply(
            &dir.join("points.ply"),
            &k.back_project_map(&f.depth_m),
            &rgb,
        )?;
    }
    Ok(tiles(f, &ann.roughness_m))
}

/// Writes `depth_sensor.png`: the model's depth, or a copy of `depth.png` (written before)
/// for the exact sensor.
fn write_sensor_depth(
    dir: &Path,
    f: &RenderedFrame,
    k: &tre_core::geometry::Intrinsics,
    model: &SensorModel,
    seed: u64,
) -> Result<(), IoError> {
    let path = dir.join("depth_sensor.png");
    if model.sensor == SensorPreset::Exact {
        std::fs::copy(dir.join("depth.png"), path)?;
        return Ok(());
    }
    let input = SensorInput {
        depth_m: &f.depth_m,
        normals_cam: &f.normals_cam,
        rgb: &f.rgb,
        intrinsics: k,
    };
    let depth_m = simulate(model, &input, seed);
    io::save(&path, &DynamicImage::ImageLuma16(io::depth_png16(&depth_m)))
}
