//! The marks on and under the map's panels: the camera's path, start and heading; the metric
//! scale bar; a layer's colour bar (ticks and unit) or its states; the symbols' key.

use image::{Rgb, RgbImage};

use super::super::style::{Scale, Style, NOT_SEEN};
use super::super::CameraMark;
use super::{GAP, HALO, LINE_H, TEXT};
use crate::colormap::traversal_rgb;
use crate::sheet::{self, arrow_head, disc, draw_text, fill, text_size, thick_line, Point};
use crate::sheet::{BACKGROUND, INK, NO_DATA};
use tre_core::roughness::traversal::Traversal;

/// Height of a colour bar, pixels.
const BAR_H: u32 = 14;
/// Length of a tick below the bar, pixels.
const TICK_H: u32 = 4;
/// Length of the heading arrow from the last pose to its tip, pixels.
const ARROW_PX: f64 = 22.0;
/// Width of a symbol in the key, pixels.
const SYMBOL_W: u32 = 28;

/// Draws the camera's path through the marks' pixels (`to_px`): a line through the positions,
/// a ring at the first, and an arrow from the last along its heading.
pub(super) fn draw_trajectory(
    img: &mut RgbImage,
    trajectory: &[CameraMark],
    to_px: impl Fn(&CameraMark) -> Point,
) {
    let points: Vec<Point> = trajectory.iter().map(&to_px).collect();
    for (radius, colour) in [(2.5, HALO), (1.2, INK)] {
        for pair in points.windows(2) {
            thick_line(img, pair[0], pair[1], radius, colour);
        }
    }
    if let Some(&first) = points.first() {
        start_mark(img, first);
    }
    if let (Some(last), Some(&p)) = (trajectory.last(), points.last()) {
        heading_mark(img, p, last.heading_rad);
    }
}

/// A ring (the path's start) centred at `p`.
fn start_mark(img: &mut RgbImage, p: Point) {
    disc(img, p, 7.0, HALO);
    disc(img, p, 5.5, INK);
    disc(img, p, 3.0, HALO);
}

/// A dot at `p` and an arrow from it towards `heading_rad` (map frame: 0 along +x, turning to
/// +y, which is up in the picture).
fn heading_mark(img: &mut RgbImage, p: Point, heading_rad: f64) {
    let dir = (heading_rad.cos(), -heading_rad.sin());
    let tip = (p.0 + ARROW_PX * dir.0, p.1 + ARROW_PX * dir.1);
    thick_line(img, p, tip, 2.5, HALO);
    disc(img, p, 4.5, HALO);
    thick_line(img, p, tip, 1.5, INK);
    disc(img, p, 3.0, INK);
    arrow_head(img, tip, dir, 11.0, INK, HALO);
}

/// A scale bar `width` pixels wide: the longest round length up to a third of the map's
/// `map_w` pixels (at least the shortest), drawn to scale with its length written after it.
pub(super) fn scale_bar(px_per_m: f64, map_w: u32, width: u32) -> RgbImage {
    const LENGTHS_M: [f64; 16] = [
        0.05, 0.1, 0.2, 0.25, 0.5, 1.0, 2.0, 2.5, 5.0, 10.0, 20.0, 25.0, 50.0, 100.0, 250.0, 500.0,
    ];
    let most = f64::from(map_w) / 3.0;
    let length_m = LENGTHS_M
        .iter()
        .copied()
        .take_while(|l| l * px_per_m <= most)
        .last()
        .unwrap_or(LENGTHS_M[0]);
    let label = if length_m >= 1.0 {
        format!("{length_m} m")
    } else {
        format!("{} cm", (length_m * 100.0).round())
    };
    let bar_px = (length_m * px_per_m).round().max(1.0) as u32;
    let mut img = RgbImage::from_pixel(width, LINE_H + 4, BACKGROUND);
    let mid = 2 + LINE_H / 2;
    fill(&mut img, 1, mid - 2, bar_px, 4, INK);
    fill(&mut img, 1, mid - 7, 2, 14, INK);
    fill(&mut img, bar_px.saturating_sub(1), mid - 7, 2, 14, INK);
    let text_y = mid.saturating_sub(sheet::GLYPH_H * TEXT / 2);
    draw_text(&mut img, bar_px + 2 + GAP, text_y, &label, TEXT, INK);
    img
}

/// The layer's legend `width` pixels wide: the colour bar with its ticks, labels and unit, or
/// the three states' swatches.
pub(super) fn legend_strip(style: &Style, width: u32) -> RgbImage {
    match &style.scale {
        Scale::States => flow(
            &[
                (Symbol::Swatch(state(Traversal::Traversable)), "traversable"),
                (Symbol::Swatch(state(Traversal::Hazard)), "hazard"),
                (Symbol::Swatch(state(Traversal::Unknown)), "unknown"),
            ],
            width,
        ),
        Scale::Continuous { lo, hi, ticks, .. } => colour_bar(style, (*lo, *hi), ticks, width),
    }
}

/// A state's colour.
fn state(t: Traversal) -> Rgb<u8> {
    Rgb(traversal_rgb(t))
}

/// The colour bar over `lo..hi` (`range`), `width` pixels wide with the unit after it (a unit
/// of several words stays in the title alone), a tick and a label at each of `ticks` (the
/// first and the last always labelled, the others where they fit).
fn colour_bar(style: &Style, (lo, hi): (f64, f64), ticks: &[f64], width: u32) -> RgbImage {
    let unit = if style.unit.contains(' ') {
        ""
    } else {
        style.unit.as_str()
    };
    let unit_w = if unit.is_empty() {
        0
    } else {
        text_size(unit, TEXT).0 + GAP
    };
    let (x0, x1) = (1, width.saturating_sub(unit_w + 1).max(3));
    let height = BAR_H + TICK_H + 2 + LINE_H + GAP;
    let mut img = RgbImage::from_pixel(width, height, BACKGROUND);
    let span = f64::from(x1 - 1 - x0);
    fill(&mut img, x0 - 1, 0, x1 - x0 + 2, BAR_H + 2, INK);
    for x in x0..x1 {
        let colour = style.bar_colour(f64::from(x - x0) / span);
        fill(&mut img, x, 1, 1, BAR_H, colour);
    }
    let text_y = 1 + (BAR_H + 2).saturating_sub(sheet::GLYPH_H * TEXT) / 2;
    draw_text(
        &mut img,
        x1 + 1 + GAP,
        text_y.saturating_sub(1),
        unit,
        TEXT,
        INK,
    );
    let at = |v: f64| x0 + (span * (v - lo) / (hi - lo)).round().clamp(0.0, span) as u32;
    let labels: Vec<(u32, String)> = ticks.iter().map(|&v| (at(v), style.label(v))).collect();
    for &(x, _) in &labels {
        fill(&mut img, x, BAR_H + 2, 1, TICK_H, INK);
    }
    let y = BAR_H + 2 + TICK_H + 2;
    for (x, label) in placed_labels(&labels, width) {
        draw_text(&mut img, x, y, &label, TEXT, INK);
    }
    img
}

/// Where the tick labels go (left edge, text): centred under their ticks within `width`; the
/// first and the last always, the others where they overlap neither a placed label.
fn placed_labels(labels: &[(u32, String)], width: u32) -> Vec<(u32, String)> {
    let span = |(x, label): &(u32, String)| {
        let w = text_size(label, TEXT).0;
        let left = x.saturating_sub(w / 2).min(width.saturating_sub(w));
        (left, left + w + sheet::ADVANCE * TEXT)
    };
    let n = labels.len();
    let mut order: Vec<usize> = [0, n.saturating_sub(1)].into_iter().collect();
    order.extend(1..n.saturating_sub(1));
    order.dedup();
    let mut placed: Vec<(u32, u32, usize)> = Vec::new();
    for i in order.into_iter().take(n) {
        let (l, r) = span(&labels[i]);
        if placed.iter().all(|&(pl, pr, _)| r <= pl || l >= pr) {
            placed.push((l, r, i));
        }
    }
    placed.sort_by_key(|p| p.2);
    placed
        .into_iter()
        .map(|(l, _, i)| (l, labels[i].1.clone()))
        .collect()
}

/// A symbol of the key.
#[derive(Debug, Clone, Copy)]
enum Symbol {
    /// A square of a colour.
    Swatch(Rgb<u8>),
    /// A piece of the camera's path.
    Path,
    /// The path's start.
    Start,
    /// The last pose and its heading.
    Heading,
}

/// The key of the symbols common to every panel, `width` pixels wide: cells not seen and
/// without data, and (`with_trajectory`) the camera's path, its start and its last heading.
pub(super) fn key_strip(width: u32, with_trajectory: bool) -> RgbImage {
    let mut entries = vec![
        (Symbol::Swatch(NOT_SEEN), "not seen"),
        (Symbol::Swatch(NO_DATA), "seen, no value"),
    ];
    if with_trajectory {
        entries.extend([
            (Symbol::Path, "camera path"),
            (Symbol::Start, "start"),
            (Symbol::Heading, "last pose, looking"),
        ]);
    }
    flow(&entries, width)
}

/// `entries` (a symbol and its label) left to right, wrapping to new rows within `width`.
fn flow(entries: &[(Symbol, &str)], width: u32) -> RgbImage {
    let entry_w = |label: &str| SYMBOL_W + GAP + text_size(label, TEXT).0 + 3 * GAP;
    let mut rows: Vec<Vec<(Symbol, &str)>> = vec![Vec::new()];
    let mut x = 0;
    for &(symbol, label) in entries {
        let w = entry_w(label);
        if x > 0 && x + w > width + 3 * GAP {
            rows.push(Vec::new());
            x = 0;
        }
        if let Some(row) = rows.last_mut() {
            row.push((symbol, label));
        }
        x += w;
    }
    let row_h = LINE_H + GAP;
    let mut img = RgbImage::from_pixel(width, GAP + rows.len() as u32 * row_h, BACKGROUND);
    for (k, row) in rows.iter().enumerate() {
        let y = GAP + k as u32 * row_h;
        let mut x = 0;
        for &(symbol, label) in row {
            draw_symbol(&mut img, symbol, x, y);
            draw_text(&mut img, x + SYMBOL_W + GAP, y + 1, label, TEXT, INK);
            x += entry_w(label);
        }
    }
    img
}

/// `symbol` in the [`SYMBOL_W`]-wide box whose top-left is (`x`, `y`).
fn draw_symbol(img: &mut RgbImage, symbol: Symbol, x: u32, y: u32) {
    let mid = (f64::from(x) + f64::from(SYMBOL_W) / 2.0, f64::from(y) + 8.5);
    let (left, right) = (
        (f64::from(x) + 2.0, mid.1),
        (f64::from(x + SYMBOL_W) - 2.0, mid.1),
    );
    match symbol {
        Symbol::Swatch(colour) => {
            fill(img, x + 6, y, 16, 16, Rgb([60, 60, 60]));
            fill(img, x + 7, y + 1, 14, 14, colour);
        }
        Symbol::Path => {
            thick_line(img, left, right, 1.2, INK);
        }
        Symbol::Start => start_mark(img, mid),
        Symbol::Heading => {
            thick_line(img, (left.0 + 4.0, left.1), right, 1.5, INK);
            disc(img, (left.0 + 4.0, left.1), 3.0, INK);
            arrow_head(img, right, (1.0, 0.0), 11.0, INK, BACKGROUND);
        }
    }
}
