//! The grid map's files, as `tre map` writes them (docs/map.md): every layer as `.npy`
//! (float32) and 16-bit `.png` (0 = no data, the scale in `map.json`), `layers.png` (the layers
//! side by side, for people) and `map.json` (the grid's geometry, layout and run figures).

use std::path::Path;

use image::{DynamicImage, Rgb, RgbImage};
use serde_json::json;
use tre_core::geometry::Grid;
use tre_core::map::{GridMap, Layers, LAYER_NAMES};

use crate::{sheet, IoError};

/// What a run of the map did, for `map.json`.
#[derive(Debug, Clone, Default)]
pub struct MapRun {
    /// Frames fused.
    pub fused: usize,
    /// Frames skipped, each with why.
    pub skipped: Vec<String>,
    /// Time each fusion took, milliseconds.
    pub fuse_ms: Vec<f64>,
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

/// Writes every layer of `map` (`layers`, read from it) into `dir` with `layers.png` and
/// `map.json`, creating `dir`; what the map shows.
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
    crate::save(
        &dir.join("layers.png"),
        &DynamicImage::ImageRgb8(picture(layers)),
    )?;
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
        "frames_fused": run.fused,
        "frames_skipped": run.skipped,
        "memory_bytes": window.memory_bytes,
        "fuse_ms_median": fuse_ms_median,
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

/// The layers side by side: elevation, roughness, slope, step, score, three-state.
fn picture(l: &Layers) -> RgbImage {
    let scaled = |g: &Grid<f32>, lo: f64, hi: f64| {
        crate::colormap::colourise(&g.map(|&v| f64::from(v)), lo, hi)
    };
    let finite = |g: &Grid<f32>| -> (f64, f64) {
        let v: Vec<f64> = g
            .as_slice()
            .iter()
            .filter(|v| v.is_finite())
            .map(|&v| f64::from(v))
            .collect();
        let lo = v.iter().copied().fold(f64::INFINITY, f64::min);
        let hi = v.iter().copied().fold(f64::NEG_INFINITY, f64::max);
        if lo.is_finite() {
            (lo, hi.max(lo + 1e-3))
        } else {
            (0.0, 1.0)
        }
    };
    let (elo, ehi) = finite(&l.elevation);
    let trav = traversal_image(l);
    let panels = [
        sheet::Panel::new(
            format!("elevation {elo:.2}..{ehi:.2} m"),
            scaled(&l.elevation, elo, ehi),
        ),
        sheet::Panel::new("roughness 0..5 cm", scaled(&l.roughness, 0.0, 0.05)),
        sheet::Panel::new("slope 0..30 deg", scaled(&l.slope, 0.0, 30.0)),
        sheet::Panel::new("step 0..10 cm", scaled(&l.step, 0.0, 0.10)),
        sheet::Panel::new("score 0..1", scaled(&l.score, 0.0, 1.0)),
        sheet::Panel::new("three-state", trav),
    ];
    let legend = map_legend();
    sheet::contact_sheet(&panels, 3, Some(&legend))
}

/// The three-state layer in the previews' colours, never-seen cells dark.
fn traversal_image(l: &Layers) -> RgbImage {
    use tre_core::roughness::traversal::Traversal;
    let (w, h) = l.traversal.size();
    RgbImage::from_fn(w as u32, h as u32, |x, y| {
        let (x, y) = (x as usize, y as usize);
        if l.count[(x, y)] == 0.0 {
            return Rgb(NOT_SEEN);
        }
        Rgb(crate::colormap::traversal_rgb(
            match l.traversal[(x, y)] as u8 {
                1 => Traversal::Traversable,
                2 => Traversal::Hazard,
                _ => Traversal::Unknown,
            },
        ))
    })
}

/// Colour of cells never seen.
const NOT_SEEN: [u8; 3] = [40, 40, 40];

/// The legend of the three-state panel.
fn map_legend() -> RgbImage {
    use tre_core::roughness::traversal::Traversal;
    let c = |t| Rgb(crate::colormap::traversal_rgb(t));
    sheet::categorical_legend(&[
        ("traversable", c(Traversal::Traversable)),
        ("hazard", c(Traversal::Hazard)),
        ("unknown", c(Traversal::Unknown)),
        ("not seen", Rgb(NOT_SEEN)),
    ])
}
