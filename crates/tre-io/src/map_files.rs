//! The grid map's files, as `tre map` writes them (docs/map.md): every layer as `.npy`
//! (float32) and 16-bit `.png` (0 = no data, the scale in `map.json`), the pictures for people
//! (`layers.png`, every layer's panel side by side, and `views/<layer>.png`, one per layer:
//! cropped to the seen cells, with colour bars, a scale bar and the camera's path;
//! `picture.rs`, `style.rs`) and `map.json` (the grid's geometry, layout and run figures).

use std::path::Path;

use image::DynamicImage;
use serde_json::json;
use tre_core::geometry::{Grid, Vec3};
use tre_core::map::{GridMap, Layers, Pose, LAYER_NAMES, LAYER_UNITS};

use crate::IoError;

mod picture;
mod style;

/// What a run of the map did, for `map.json`.
#[derive(Debug, Clone, Default)]
pub struct MapRun {
    /// Frames fused.
    pub fused: usize,
    /// Frames skipped, each with why.
    pub skipped: Vec<String>,
    /// Time each fusion took, milliseconds.
    pub fuse_ms: Vec<f64>,
    /// Per frame, how far the map's gravity is from the sequence's stated one, degrees (NaN:
    /// either unknown).
    pub gravity_deg: Vec<f64>,
    /// Where the camera was and looked at each fused frame, in order (drawn on the pictures).
    pub trajectory: Vec<CameraMark>,
}

/// The camera at one frame, in the map frame (x east, y north as the layers lie: column 0 at
/// the smallest x, row 0 at the largest y).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CameraMark {
    /// The camera centre's x, metres.
    pub x_m: f64,
    /// The camera centre's y, metres.
    pub y_m: f64,
    /// Where its optical axis points, projected on the x–y plane: radians from +x towards +y.
    pub heading_rad: f64,
}

impl CameraMark {
    /// The camera at `pose` (camera to world) in `map`'s frame.
    pub fn of(map: &GridMap, pose: &Pose) -> Self {
        let c = map.camera_in_map(pose);
        let axis = map.frame().map_from_world * (pose.rotation * Vec3::new(0.0, 0.0, 1.0));
        Self {
            x_m: c.x,
            y_m: c.y,
            heading_rad: axis.y.atan2(axis.x),
        }
    }
}

/// What the written map shows, for a summary line.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MapSummary {
    /// Cells seen at least once.
    pub seen: usize,
    /// Shares of the seen cells: traversable, hazard, unknown.
    pub traversable: f64,
    /// Share of the seen cells that are hazards.
    pub hazard: f64,
    /// Share of the seen cells that are unknown.
    pub unknown: f64,
    /// Median time of one fusion, milliseconds (NaN: none).
    pub fuse_ms_median: f64,
}

/// Where a map's window lies, for `map.json`: as a [`GridMap`] states it, or as a stream's
/// map update does.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MapWindow {
    /// Cell side, metres.
    pub cell_m: f64,
    /// Cells along a side.
    pub side: usize,
    /// World cell index (x, y) of the window's lower-left cell.
    pub origin: (i64, i64),
    /// Rotation from the pose frame to the map frame, row by row.
    pub map_from_world: [f64; 9],
    /// Memory the map holds, bytes, when known.
    pub memory_bytes: Option<usize>,
}

impl MapWindow {
    /// The window of `map`.
    pub fn of(map: &GridMap) -> Self {
        let cfg = map.config();
        let r = map.frame().map_from_world;
        let mut rows = [0.0; 9];
        for (k, v) in rows.iter_mut().enumerate() {
            *v = r[(k / 3, k % 3)];
        }
        Self {
            cell_m: cfg.cell_m,
            side: cfg.side,
            origin: map.origin(),
            map_from_world: rows,
            memory_bytes: Some(map.memory_bytes()),
        }
    }

    /// The window's centre in the map frame, metres.
    pub fn centre(&self) -> (f64, f64) {
        let half = (self.side / 2) as f64;
        (
            (self.origin.0 as f64 + half) * self.cell_m,
            (self.origin.1 as f64 + half) * self.cell_m,
        )
    }
}

/// Writes every layer of `map` (`layers`, read from it) into `dir` with the pictures
/// (`layers.png`, `views/<layer>.png`) and `map.json`, creating `dir`; what the map shows.
pub fn write_map(
    dir: &Path,
    map: &GridMap,
    layers: &Layers,
    run: &MapRun,
) -> Result<MapSummary, IoError> {
    write_map_window(dir, &MapWindow::of(map), layers, run)
}

/// Writes `layers` of a map whose window is `window` into `dir` as [`write_map`] does.
pub fn write_map_window(
    dir: &Path,
    window: &MapWindow,
    layers: &Layers,
    run: &MapRun,
) -> Result<MapSummary, IoError> {
    crate::paths::create_dir(dir)?;
    let mut meta = serde_json::Map::new();
    for (name, grid) in LAYER_NAMES.iter().zip(layers.all()) {
        meta.insert((*name).to_owned(), write_layer(dir, name, grid)?);
    }
    let crop = write_pictures(dir, window, layers, run)?;
    let (traversable, hazard, unknown, seen) = shares(&layers.traversal, &layers.count);
    let mut fuse_ms = run.fuse_ms.clone();
    fuse_ms.sort_by(f64::total_cmp);
    let fuse_ms_median = fuse_ms.get(fuse_ms.len() / 2).copied().unwrap_or(f64::NAN);
    let geometry = json!({
        "cell_m": window.cell_m,
        "side_cells": window.side,
        "origin_cell": [window.origin.0, window.origin.1],
        "centre_m": [window.centre().0, window.centre().1],
        "map_from_world": window.map_from_world,
        "layout": "row-major (side, side) float32; column 0 at the smallest x, row 0 at the largest y; the cell of column c, row r spans x in [(origin_x + c)·cell, +cell), y in [(origin_y + side − 1 − r)·cell, +cell) of the map frame (z up)",
        "png": "16-bit grey: 0 = no data, else value = png_offset + (png − 1)·png_scale",
        "layers": meta,
        "picture": picture_json(window, crop),
        "frames_fused": run.fused,
        "frames_skipped": run.skipped,
        "memory_bytes": window.memory_bytes,
        "fuse_ms_median": fuse_ms_median,
        "gravity_error_deg": run.gravity_deg.iter().map(|v| v.is_finite().then_some(*v)).collect::<Vec<_>>(),
    });
    let text = serde_json::to_string_pretty(&geometry).unwrap_or_default();
    crate::paths::write_text(&dir.join("map.json"), &text)?;
    Ok(MapSummary {
        seen,
        traversable,
        hazard,
        unknown,
        fuse_ms_median,
    })
}

/// Writes layer `name` as `<name>.npy` (float32) and `<name>.png` (16-bit, 0 = no data) into
/// `dir`; its unit and PNG scale for `map.json`.
fn write_layer(dir: &Path, name: &str, grid: &Grid<f32>) -> Result<serde_json::Value, IoError> {
    let g64 = grid.map(|&v| f64::from(v));
    crate::write_npy_f32(&dir.join(format!("{name}.npy")), &g64)?;
    let (scale, offset, unit) = png_scale(name, &g64);
    let png = Grid::from_fn(g64.width(), g64.height(), |x, y| {
        let v = g64[(x, y)];
        if v.is_finite() {
            (1.0 + ((v - offset) / scale).round()).clamp(1.0, 65535.0) as u16
        } else {
            0
        }
    });
    let (w, h) = (png.width() as u32, png.height() as u32);
    let img = image::ImageBuffer::<image::Luma<u16>, Vec<u16>>::from_raw(w, h, png.into_vec())
        .expect("a grid's size matches its data; this is a bug");
    crate::save(
        &dir.join(format!("{name}.png")),
        &DynamicImage::ImageLuma16(img),
    )?;
    Ok(json!({"unit": unit, "png_scale": scale, "png_offset": offset}))
}

/// Scale, offset and unit of a layer's 16-bit PNG.
fn png_scale(name: &str, g: &Grid<f64>) -> (f64, f64, &'static str) {
    let min = g
        .as_slice()
        .iter()
        .copied()
        .filter(|v| v.is_finite())
        .fold(f64::INFINITY, f64::min);
    let min = if min.is_finite() { min } else { 0.0 };
    match name {
        "elevation" => (0.0005, (min * 100.0).floor() / 100.0, "m"),
        "variance" => (1e-8, 0.0, "m^2"),
        "count" => (1.0, 0.0, "measurements"),
        "roughness" | "step" => (0.0001, 0.0, "m"),
        "slope" => (0.01, 0.0, "degrees"),
        "score" => (1.0 / 10000.0, 0.0, "0 to 1"),
        "traversal" => (1.0, 0.0, "0 unknown, 1 traversable, 2 hazard"),
        _ => (0.01, (min * 100.0).floor() / 100.0, "s"),
    }
}

/// Shares of traversable, hazard and unknown among the seen cells, and the seen cells.
fn shares(traversal: &Grid<f32>, count: &Grid<f32>) -> (f64, f64, f64, usize) {
    let seen: Vec<f32> = traversal
        .as_slice()
        .iter()
        .zip(count.as_slice())
        .filter(|(_, &c)| c > 0.0)
        .map(|(&t, _)| t)
        .collect();
    let n = seen.len().max(1) as f64;
    let share = |s: f32| seen.iter().filter(|&&t| t == s).count() as f64 / n;
    (share(1.0), share(2.0), share(0.0), seen.len())
}

/// Writes the pictures for people: `layers.png` (every layer) and `views/<layer>.png`; the
/// cells they show.
fn write_pictures(
    dir: &Path,
    window: &MapWindow,
    layers: &Layers,
    run: &MapRun,
) -> Result<picture::Crop, IoError> {
    let refs: Vec<picture::LayerRef<'_>> = LAYER_NAMES
        .iter()
        .zip(LAYER_UNITS)
        .zip(layers.all())
        .map(|((name, unit), grid)| picture::LayerRef { name, unit, grid })
        .collect();
    let pictures = picture::pictures(&refs, window, &run.trajectory, run.fused);
    crate::save(
        &dir.join("layers.png"),
        &DynamicImage::ImageRgb8(pictures.sheet),
    )?;
    let views = dir.join("views");
    crate::paths::create_dir(&views)?;
    for (name, view) in pictures.views {
        crate::save(
            &views.join(format!("{name}.png")),
            &DynamicImage::ImageRgb8(view),
        )?;
    }
    Ok(pictures.crop)
}

/// What the pictures show, for `map.json`: the columns and rows of the window, the metres and
/// the pixels a cell.
fn picture_json(window: &MapWindow, crop: picture::Crop) -> serde_json::Value {
    json!({
        "files": "layers.png (every layer), views/<layer>.png (one each)",
        "columns": [crop.c0, crop.c0 + crop.w],
        "rows": [crop.r0, crop.r0 + crop.h],
        "shown_m": [crop.w as f64 * window.cell_m, crop.h as f64 * window.cell_m],
        "pixels_per_cell": crop.px
    })
}
