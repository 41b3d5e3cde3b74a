//! The legends under a contact sheet: the Turbo colour bar with its ticks, categorical
//! swatches, and strips stacked into one legend.

use image::{imageops, Rgb, RgbImage};

use super::font::{draw_text, fill, text_size, ADVANCE, GLYPH_H};
use super::{roughness_colour, BACKGROUND, INK, MARGIN, NO_DATA, TEXT_SCALE};

/// Height of the colour bar, pixels.
const BAR_H: u32 = 16;
/// Length of a tick mark below the bar, pixels.
const TICK_H: u32 = 5;
/// Side of a legend swatch, pixels.
const SWATCH: u32 = 16;

/// `v` with at most 2 decimals and no trailing zeros: `2`, `0.5`, `1.25`.
fn short_number(v: f64) -> String {
    let s = format!("{v:.2}");
    s.trim_end_matches('0').trim_end_matches('.').to_owned()
}

/// A legend strip `width` pixels wide: "roughness", the Turbo bar over `[0, max_m]` with a
/// tick and a label at each of `ticks_cm` (centimetres; ones outside the scale are left out,
/// and a label that would overlap the previous one is skipped), "cm", and a grey swatch
/// saying "no data". The bar's first column is the colour of 0 and its last that of `max_m`,
/// exactly as [`roughness_panel`](super::roughness_panel) draws them.
pub fn colour_bar_legend(width: u32, max_m: f64, ticks_cm: &[f64]) -> RgbImage {
    let (width, bar_x0, bar_x1) = bar_layout(width);
    let (unit_w, text_h) = text_size("cm", TEXT_SCALE);
    let height = MARGIN + BAR_H + TICK_H + 2 + text_h + MARGIN;
    let mut img = RgbImage::from_pixel(width, height, BACKGROUND);
    let text_y = MARGIN + (BAR_H - text_h) / 2;
    draw_text(&mut img, MARGIN, text_y, "roughness", TEXT_SCALE, INK);
    let span = f64::from(bar_x1 - 1 - bar_x0);
    for x in bar_x0..bar_x1 {
        let v_m = max_m * f64::from(x - bar_x0) / span;
        fill(&mut img, x, MARGIN, 1, BAR_H, roughness_colour(v_m, max_m));
    }
    draw_ticks(&mut img, (bar_x0, bar_x1), max_m, ticks_cm);
    draw_text(&mut img, bar_x1 + MARGIN, text_y, "cm", TEXT_SCALE, INK);
    let swatch_x = bar_x1 + MARGIN + unit_w + 3 * MARGIN;
    swatch(&mut img, swatch_x, MARGIN, NO_DATA);
    let label_x = swatch_x + SWATCH + MARGIN;
    draw_text(&mut img, label_x, text_y, "no data", TEXT_SCALE, INK);
    img
}

/// The legend's width (at least `width`, enough for a 64-pixel bar) and its bar's first and
/// past-the-end columns.
fn bar_layout(width: u32) -> (u32, u32, u32) {
    let (label_w, _) = text_size("roughness", TEXT_SCALE);
    let (unit_w, _) = text_size("cm", TEXT_SCALE);
    let (no_data_w, _) = text_size("no data", TEXT_SCALE);
    let bar_x0 = MARGIN + label_w + 2 * MARGIN;
    let tail = MARGIN + unit_w + 3 * MARGIN + SWATCH + MARGIN + no_data_w + MARGIN;
    let width = width.max(bar_x0 + 64 + tail);
    (width, bar_x0, width - tail)
}

/// Tick marks under the bar spanning columns `bar.0..bar.1`, with their labels.
fn draw_ticks(img: &mut RgbImage, bar: (u32, u32), max_m: f64, ticks_cm: &[f64]) {
    let max_cm = max_m * 100.0;
    let span = f64::from(bar.1 - 1 - bar.0);
    let y = MARGIN + BAR_H;
    let mut free_from = 0;
    for &tick in ticks_cm {
        if !(tick >= 0.0 && tick <= max_cm) {
            continue;
        }
        let x = bar.0 + (span * tick / max_cm).round() as u32;
        fill(img, x, y, 1, TICK_H, INK);
        let label = short_number(tick);
        let (w, _) = text_size(&label, TEXT_SCALE);
        let left = x.saturating_sub(w / 2).min(img.width().saturating_sub(w));
        if left >= free_from {
            draw_text(img, left, y + TICK_H + 2, &label, TEXT_SCALE, INK);
            free_from = left + w + ADVANCE * TEXT_SCALE;
        }
    }
}

/// A [`SWATCH`]-sized square of `colour` with a dark outline, top-left at (`x`, `y`).
fn swatch(img: &mut RgbImage, x: u32, y: u32, colour: Rgb<u8>) {
    fill(img, x, y, SWATCH, SWATCH, Rgb([60, 60, 60]));
    fill(img, x + 1, y + 1, SWATCH - 2, SWATCH - 2, colour);
}

/// A legend strip of coloured swatches, each followed by its label, left to right (e.g.
/// traversable / hazard / unknown).
pub fn categorical_legend(entries: &[(&str, Rgb<u8>)]) -> RgbImage {
    let text_h = GLYPH_H * TEXT_SCALE;
    let entry_w = |label: &str| SWATCH + MARGIN + text_size(label, TEXT_SCALE).0 + 3 * MARGIN;
    let width = MARGIN + entries.iter().map(|(l, _)| entry_w(l)).sum::<u32>();
    let height = 2 * MARGIN + SWATCH.max(text_h);
    let mut img = RgbImage::from_pixel(width, height, BACKGROUND);
    let mut x = MARGIN;
    for (label, colour) in entries {
        swatch(&mut img, x, MARGIN, *colour);
        let text_y = MARGIN + SWATCH.saturating_sub(text_h) / 2;
        draw_text(
            &mut img,
            x + SWATCH + MARGIN,
            text_y,
            label,
            TEXT_SCALE,
            INK,
        );
        x += entry_w(label);
    }
    img
}

/// `strips` one above the other, each centred, on the background: e.g. a colour bar and a
/// categorical legend as the one legend of a [`contact_sheet`](super::contact_sheet).
pub fn stack(strips: &[RgbImage]) -> RgbImage {
    let width = strips.iter().map(RgbImage::width).max().unwrap_or(0);
    let height = strips.iter().map(RgbImage::height).sum();
    let mut out = RgbImage::from_pixel(width, height, BACKGROUND);
    let mut y = 0;
    for strip in strips {
        let x = (width - strip.width()) / 2;
        imageops::replace(&mut out, strip, i64::from(x), i64::from(y));
        y += strip.height();
    }
    out
}

#[cfg(test)]
mod tests {
    use super::super::{ink_pixels, roughness_panel};
    use super::*;
    use tre_core::geometry::Grid;

    #[test]
    fn the_bar_runs_from_the_colour_of_zero_to_that_of_max() {
        let max_m = 0.1;
        let legend = colour_bar_legend(500, max_m, &[0.0, 1.0, 2.0, 5.0, 10.0]);
        let map = Grid::from_vec(2, 1, vec![0.0, max_m]).unwrap();
        let panel = roughness_panel(&map, max_m);
        let y = MARGIN + BAR_H / 2;
        let row: Vec<_> = (0..legend.width())
            .map(|x| *legend.get_pixel(x, y))
            .collect();
        let first = row.iter().position(|p| *p == *panel.get_pixel(0, 0));
        let last = row.iter().rposition(|p| *p == *panel.get_pixel(1, 0));
        let (_, bar_x0, bar_x1) = bar_layout(500);
        assert_eq!(
            (first, last),
            (Some(bar_x0 as usize), Some(bar_x1 as usize - 1))
        );
        assert!(bar_x1 - bar_x0 > 150, "{bar_x0}..{bar_x1}");
        let bar = &row[bar_x0 as usize..bar_x1 as usize];
        assert!(bar.iter().all(|p| *p != BACKGROUND && *p != NO_DATA));
        assert_eq!(legend.width(), 500);
        assert_eq!(colour_bar_legend(10, max_m, &[]).width(), bar_layout(0).0);
    }

    #[test]
    fn ticks_outside_the_scale_are_left_out() {
        let ticks = |t: &[f64]| ink_pixels(&colour_bar_legend(500, 0.05, t)).len();
        assert_eq!(ticks(&[1.0]), ticks(&[1.0, 7.0, -1.0, f64::NAN]));
        assert!(ticks(&[1.0, 2.0]) > ticks(&[1.0]));
    }

    #[test]
    fn categorical_legend_shows_each_colour() {
        let entries = [
            ("traversable", Rgb([40, 170, 60])),
            ("hazard", Rgb([220, 50, 40])),
            ("unknown", NO_DATA),
        ];
        let img = categorical_legend(&entries);
        for (label, colour) in entries {
            assert!(img.pixels().any(|p| *p == colour), "{label}");
        }
        assert!(img.width() > text_size("traversablehazardunknown", TEXT_SCALE).0);
    }

    #[test]
    fn stack_centres_each_strip_below_the_previous() {
        let red = Rgb([255, 0, 0]);
        let strips = [RgbImage::new(30, 5), RgbImage::from_pixel(10, 4, red)];
        let out = stack(&strips);
        assert_eq!(out.dimensions(), (30, 9));
        assert_eq!(*out.get_pixel(10, 5), red);
        assert_eq!(*out.get_pixel(9, 5), BACKGROUND);
        assert_eq!(*out.get_pixel(19, 8), red);
    }
}
