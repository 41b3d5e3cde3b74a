//! The contact sheet: one row of tiles per previewed frame, stacked.

use image::RgbImage;

use crate::render::RenderedFrame;
use tre_core::geometry::{Grid, Vec3};
use tre_io as io;

/// One contact-sheet row: rgb | depth | normals | labels | roughness (0–5 cm).
pub(super) fn tiles(f: &RenderedFrame, roughness_m: &Grid<f64>) -> RgbImage {
    let (w, h) = (f.rgb.width(), f.rgb.height());
    let depth_or_nan = f.depth_m.map(|&d| if d > 0.0 { d } else { f64::NAN });
    let depth = io::colormap::colourise(&depth_or_nan, 0.0, 3.0);
    let normals = RgbImage::from_fn(w, h, |u, v| {
        let n: Vec3 = f.normals_cam[(u as usize, v as usize)];
        image::Rgb(if n.x.is_finite() {
            [0, 1, 2].map(|c| ((0.5 - 0.5 * n[c]) * 255.0) as u8)
        } else {
            [0; 3]
        })
    });
    let labels = io::colormap::labels(&f.labels);
    let rough = io::colormap::colourise(roughness_m, 0.0, 0.05);
    let mut row = RgbImage::new(w * 5, h);
    for (i, t) in [&f.rgb, &depth, &normals, &labels, &rough]
        .into_iter()
        .enumerate()
    {
        image::imageops::replace(&mut row, t, i64::from(w) * i as i64, 0);
    }
    row
}

/// Stacks contact-sheet rows, each scaled to 160 px high.
pub(super) fn contact_sheet(rows: &[RgbImage]) -> RgbImage {
    let scaled: Vec<RgbImage> = rows
        .iter()
        .map(|r| {
            let w = (r.width() as f64 * 160.0 / r.height() as f64) as u32;
            image::imageops::resize(r, w.max(1), 160, image::imageops::FilterType::Triangle)
        })
        .collect();
    let width = scaled.iter().map(RgbImage::width).max().unwrap_or(1);
    let mut sheet = RgbImage::new(width, 160 * scaled.len().max(1) as u32);
    for (i, r) in scaled.iter().enumerate() {
        image::imageops::replace(&mut sheet, r, 0, 160 * i as i64);
    }
    sheet
}
