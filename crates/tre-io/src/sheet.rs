//! Contact sheets for people: titled panels in a grid, roughness maps in one shared Turbo scale,
//! a colour-bar or categorical legend, and the 5×8 bitmap font that writes their text.
//!
//! A benchmark writes one sheet per frame ("RGB | spec | rgb | rgbd | geometric"): every
//! roughness panel is drawn by [`roughness_panel`] with the same `max_m`, so equal colours mean
//! equal roughness across panels, and [`colour_bar_legend`] states that scale below the grid.

use image::{imageops, Rgb, RgbImage};

use super::colormap::turbo;
use tre_core::geometry::Grid;

/// Width of a glyph of [`draw_text`] at scale 1, pixels.
pub const GLYPH_W: u32 = 5;
/// Height of a glyph cell at scale 1 (7 rows above the baseline, 1 for descenders), pixels.
pub const GLYPH_H: u32 = 8;
/// Horizontal distance from one glyph to the next at scale 1, pixels.
pub const ADVANCE: u32 = GLYPH_W + 1;

/// Colour of roughness pixels without data: a neutral grey that Turbo never takes.
pub const NO_DATA: Rgb<u8> = Rgb([112, 112, 112]);
/// Colour of depth pixels without data in [`depth_panel`].
pub const NO_DEPTH: Rgb<u8> = Rgb([0, 0, 0]);
/// Sheet and legend background.
pub const BACKGROUND: Rgb<u8> = Rgb([255, 255, 255]);
/// Text colour on [`BACKGROUND`].
pub const INK: Rgb<u8> = Rgb([0, 0, 0]);

/// Gap around and between panels, pixels.
const MARGIN: u32 = 8;
/// Font scale of titles and legend text.
const TEXT_SCALE: u32 = 2;
/// Height of the title strip above each panel, pixels.
const TITLE_H: u32 = GLYPH_H * TEXT_SCALE + 6;
/// Height of the colour bar, pixels.
const BAR_H: u32 = 16;
/// Length of a tick mark below the bar, pixels.
const TICK_H: u32 = 5;
/// Side of a legend swatch, pixels.
const SWATCH: u32 = 16;

/// ASCII 32 (space) to 126 (`~`), 5 columns each, bit 0 the top row; bit 7 holds descenders.
const FONT: [[u8; 5]; 95] = [
    [0x00, 0x00, 0x00, 0x00, 0x00], // ' '
    [0x00, 0x00, 0x5F, 0x00, 0x00], // !
    [0x00, 0x07, 0x00, 0x07, 0x00], // "
    [0x14, 0x7F, 0x14, 0x7F, 0x14], // #
    [0x24, 0x2A, 0x7F, 0x2A, 0x12], // $
    [0x23, 0x13, 0x08, 0x64, 0x62], // %
    [0x36, 0x49, 0x56, 0x20, 0x50], // &
    [0x00, 0x00, 0x07, 0x00, 0x00], // '
    [0x00, 0x1C, 0x22, 0x41, 0x00], // (
    [0x00, 0x41, 0x22, 0x1C, 0x00], // )
    [0x2A, 0x1C, 0x7F, 0x1C, 0x2A], // *
    [0x08, 0x08, 0x3E, 0x08, 0x08], // +
    [0x00, 0x80, 0x70, 0x30, 0x00], // ,
    [0x08, 0x08, 0x08, 0x08, 0x08], // -
    [0x00, 0x00, 0x60, 0x60, 0x00], // .
    [0x20, 0x10, 0x08, 0x04, 0x02], // /
    [0x3E, 0x51, 0x49, 0x45, 0x3E], // 0
    [0x00, 0x42, 0x7F, 0x40, 0x00], // 1
    [0x72, 0x49, 0x49, 0x49, 0x46], // 2
    [0x21, 0x41, 0x49, 0x4D, 0x33], // 3
    [0x18, 0x14, 0x12, 0x7F, 0x10], // 4
    [0x27, 0x45, 0x45, 0x45, 0x39], // 5
    [0x3C, 0x4A, 0x49, 0x49, 0x31], // 6
    [0x41, 0x21, 0x11, 0x09, 0x07], // 7
    [0x36, 0x49, 0x49, 0x49, 0x36], // 8
    [0x46, 0x49, 0x49, 0x29, 0x1E], // 9
    [0x00, 0x00, 0x14, 0x00, 0x00], // :
    [0x00, 0x40, 0x34, 0x00, 0x00], // ;
    [0x00, 0x08, 0x14, 0x22, 0x41], // <
    [0x14, 0x14, 0x14, 0x14, 0x14], // =
    [0x00, 0x41, 0x22, 0x14, 0x08], // >
    [0x02, 0x01, 0x59, 0x09, 0x06], // ?
    [0x3E, 0x41, 0x5D, 0x59, 0x4E], // @
    [0x7C, 0x12, 0x11, 0x12, 0x7C], // A
    [0x7F, 0x49, 0x49, 0x49, 0x36], // B
    [0x3E, 0x41, 0x41, 0x41, 0x22], // C
    [0x7F, 0x41, 0x41, 0x41, 0x3E], // D
    [0x7F, 0x49, 0x49, 0x49, 0x41], // E
    [0x7F, 0x09, 0x09, 0x09, 0x01], // F
    [0x3E, 0x41, 0x41, 0x51, 0x73], // G
    [0x7F, 0x08, 0x08, 0x08, 0x7F], // H
    [0x00, 0x41, 0x7F, 0x41, 0x00], // I
    [0x20, 0x40, 0x41, 0x3F, 0x01], // J
    [0x7F, 0x08, 0x14, 0x22, 0x41], // K
    [0x7F, 0x40, 0x40, 0x40, 0x40], // L
    [0x7F, 0x02, 0x1C, 0x02, 0x7F], // M
    [0x7F, 0x04, 0x08, 0x10, 0x7F], // N
    [0x3E, 0x41, 0x41, 0x41, 0x3E], // O
    [0x7F, 0x09, 0x09, 0x09, 0x06], // P
    [0x3E, 0x41, 0x51, 0x21, 0x5E], // Q
    [0x7F, 0x09, 0x19, 0x29, 0x46], // R
    [0x26, 0x49, 0x49, 0x49, 0x32], // S
    [0x01, 0x01, 0x7F, 0x01, 0x01], // T
    [0x3F, 0x40, 0x40, 0x40, 0x3F], // U
    [0x1F, 0x20, 0x40, 0x20, 0x1F], // V
    [0x3F, 0x40, 0x38, 0x40, 0x3F], // W
    [0x63, 0x14, 0x08, 0x14, 0x63], // X
    [0x03, 0x04, 0x78, 0x04, 0x03], // Y
    [0x61, 0x51, 0x49, 0x45, 0x43], // Z
    [0x00, 0x7F, 0x41, 0x41, 0x00], // [
    [0x02, 0x04, 0x08, 0x10, 0x20], // \
    [0x00, 0x41, 0x41, 0x7F, 0x00], // ]
    [0x04, 0x02, 0x01, 0x02, 0x04], // ^
    [0x40, 0x40, 0x40, 0x40, 0x40], // _
    [0x00, 0x01, 0x02, 0x04, 0x00], // `
    [0x20, 0x54, 0x54, 0x54, 0x78], // a
    [0x7F, 0x48, 0x44, 0x44, 0x38], // b
    [0x38, 0x44, 0x44, 0x44, 0x28], // c
    [0x38, 0x44, 0x44, 0x48, 0x7F], // d
    [0x38, 0x54, 0x54, 0x54, 0x18], // e
    [0x08, 0x7E, 0x09, 0x01, 0x02], // f
    [0x18, 0xA4, 0xA4, 0xA4, 0x7C], // g
    [0x7F, 0x08, 0x04, 0x04, 0x78], // h
    [0x00, 0x44, 0x7D, 0x40, 0x00], // i
    [0x40, 0x80, 0x84, 0x7D, 0x00], // j
    [0x7F, 0x10, 0x28, 0x44, 0x00], // k
    [0x00, 0x41, 0x7F, 0x40, 0x00], // l
    [0x7C, 0x04, 0x78, 0x04, 0x78], // m
    [0x7C, 0x08, 0x04, 0x04, 0x78], // n
    [0x38, 0x44, 0x44, 0x44, 0x38], // o
    [0xFC, 0x24, 0x24, 0x24, 0x18], // p
    [0x18, 0x24, 0x24, 0x24, 0xFC], // q
    [0x7C, 0x08, 0x04, 0x04, 0x08], // r
    [0x48, 0x54, 0x54, 0x54, 0x24], // s
    [0x04, 0x3F, 0x44, 0x40, 0x20], // t
    [0x3C, 0x40, 0x40, 0x20, 0x7C], // u
    [0x1C, 0x20, 0x40, 0x20, 0x1C], // v
    [0x3C, 0x40, 0x30, 0x40, 0x3C], // w
    [0x44, 0x28, 0x10, 0x28, 0x44], // x
    [0x1C, 0xA0, 0xA0, 0xA0, 0x7C], // y
    [0x44, 0x64, 0x54, 0x4C, 0x44], // z
    [0x00, 0x08, 0x36, 0x41, 0x00], // {
    [0x00, 0x00, 0x7F, 0x00, 0x00], // |
    [0x00, 0x41, 0x36, 0x08, 0x00], // }
    [0x08, 0x04, 0x08, 0x10, 0x08], // ~
];

/// The columns of `c`'s glyph; characters outside ASCII 32–126 draw as `?`.
fn glyph(c: char) -> [u8; 5] {
    let index = u32::from(c)
        .checked_sub(32)
        .filter(|&i| i < 95)
        .unwrap_or(u32::from('?') - 32);
    FONT[index as usize]
}

/// Width and height of `text` drawn by [`draw_text`] at `scale`, pixels (one line; no
/// spacing after the last glyph).
///
/// ```
/// assert_eq!(tre_io::sheet::text_size("ab", 2), (22, 16));
/// ```
pub fn text_size(text: &str, scale: u32) -> (u32, u32) {
    let n = text.chars().count() as u32;
    let w = (n * ADVANCE).saturating_sub(1) * scale;
    (w, GLYPH_H * scale)
}

/// Writes one line of `text` with its glyph cell's top-left corner at (`x`, `y`), each font
/// pixel a `scale`×`scale` square of `colour`; what falls outside `img` is clipped.
pub fn draw_text(img: &mut RgbImage, x: u32, y: u32, text: &str, scale: u32, colour: Rgb<u8>) {
    for (i, c) in text.chars().enumerate() {
        let x0 = x.saturating_add(i as u32 * ADVANCE * scale);
        for (col, bits) in glyph(c).iter().enumerate() {
            for row in 0..GLYPH_H {
                if bits & (1 << row) != 0 {
                    let px = x0.saturating_add(col as u32 * scale);
                    fill(img, px, y.saturating_add(row * scale), scale, scale, colour);
                }
            }
        }
    }
}

/// Fills the `w`×`h` rectangle at (`x`, `y`), clipped to `img`.
fn fill(img: &mut RgbImage, x: u32, y: u32, w: u32, h: u32, colour: Rgb<u8>) {
    let (x1, y1) = (
        x.saturating_add(w).min(img.width()),
        y.saturating_add(h).min(img.height()),
    );
    for yy in y..y1 {
        for xx in x..x1 {
            img.put_pixel(xx, yy, colour);
        }
    }
}

/// `text` cut to at most `max_w` pixels at `scale`, ending in `..` when cut.
fn fit_text(text: &str, max_w: u32, scale: u32) -> String {
    if text_size(text, scale).0 <= max_w {
        return text.to_owned();
    }
    let keep = (max_w / scale + 1) / ADVANCE;
    let mut cut: String = text.chars().take(keep.saturating_sub(2) as usize).collect();
    cut.push_str("..");
    cut
}

/// One titled image of a [`contact_sheet`].
#[derive(Debug, Clone)]
pub struct Panel {
    /// Written above the image (cut with `..` when wider than the cell).
    pub title: String,
    /// The image, placed at its own size.
    pub image: RgbImage,
}

impl Panel {
    /// A panel titled `title`.
    pub fn new(title: impl Into<String>, image: RgbImage) -> Self {
        Self {
            title: title.into(),
            image,
        }
    }
}

/// The panels in a grid of `columns` (clamped to 1..=panels), row by row, each under its title,
/// and `legend` centred below the grid.
///
/// Every cell is as large as the largest panel; a smaller panel is centred in its cell on the
/// white background, never scaled (bring images to one size first, e.g. with
/// [`fit_within`], when pixels should line up). The sheet is `8 + columns × (cell_w + 8)`
/// wide, at least the legend's width plus 16 (the grid then centred), and
/// `8 + rows × (22 + cell_h + 8)` high, plus the legend's height and 8 when there is one.
///
/// ```
/// use image::{Rgb, RgbImage};
/// use tre_io::sheet::{contact_sheet, Panel};
///
/// let panels: Vec<Panel> = ["RGB", "rgb", "rgbd"]
///     .into_iter()
///     .map(|t| Panel::new(t, RgbImage::from_pixel(64, 48, Rgb([200, 50, 50]))))
///     .collect();
/// let sheet = contact_sheet(&panels, 2, None);
/// assert_eq!(sheet.dimensions(), (8 + 2 * (64 + 8), 8 + 2 * (22 + 48 + 8)));
/// ```
pub fn contact_sheet(panels: &[Panel], columns: usize, legend: Option<&RgbImage>) -> RgbImage {
    let columns = columns.clamp(1, panels.len().max(1)) as u32;
    let rows = (panels.len() as u32).div_ceil(columns);
    let cell_w = panels.iter().map(|p| p.image.width()).max().unwrap_or(0);
    let cell_h = panels.iter().map(|p| p.image.height()).max().unwrap_or(0);
    let row_h = TITLE_H + cell_h + MARGIN;
    let grid_w = MARGIN + columns * (cell_w + MARGIN);
    let legend_size = legend.map_or((0, 0), |l| (l.width() + 2 * MARGIN, l.height() + MARGIN));
    let width = grid_w.max(legend_size.0);
    let height = MARGIN + rows * row_h + legend_size.1;
    let mut sheet = RgbImage::from_pixel(width, height, BACKGROUND);
    for (i, panel) in panels.iter().enumerate() {
        let (col, row) = (i as u32 % columns, i as u32 / columns);
        let x = (width - grid_w) / 2 + MARGIN + col * (cell_w + MARGIN);
        let y = MARGIN + row * row_h;
        let title = fit_text(&panel.title, cell_w, TEXT_SCALE);
        draw_text(&mut sheet, x, y + 2, &title, TEXT_SCALE, INK);
        let (dx, dy) = (
            (cell_w - panel.image.width()) / 2,
            (cell_h - panel.image.height()) / 2,
        );
        imageops::replace(
            &mut sheet,
            &panel.image,
            i64::from(x + dx),
            i64::from(y + TITLE_H + dy),
        );
    }
    if let Some(legend) = legend {
        let x = (width - legend.width()) / 2;
        imageops::replace(
            &mut sheet,
            legend,
            i64::from(x),
            i64::from(height - legend_size.1),
        );
    }
    sheet
}

/// Turbo colour of `v_m` on the scale `[0, max_m]` (clamped); non-finite: [`NO_DATA`].
fn roughness_colour(v_m: f64, max_m: f64) -> Rgb<u8> {
    if !v_m.is_finite() {
        return NO_DATA;
    }
    let t = if max_m > 0.0 { v_m / max_m } else { 1.0 };
    Rgb(turbo(t))
}

/// Roughness (metres; NaN or infinite: no data) in Turbo over `[0, max_m]` (the project's
/// preview colour map; values above `max_m` take its top colour), pixels without data in
/// [`NO_DATA`] grey. Use one `max_m` for every panel of a sheet.
pub fn roughness_panel(roughness_m: &Grid<f64>, max_m: f64) -> RgbImage {
    RgbImage::from_fn(
        roughness_m.width() as u32,
        roughness_m.height() as u32,
        |x, y| roughness_colour(roughness_m[(x as usize, y as usize)], max_m),
    )
}

/// Depth (metres) in grey: near white to far (`max_m` and beyond) dark grey; zero, negative
/// or non-finite depth (no data) in [`NO_DEPTH`] black.
pub fn depth_panel(depth_m: &Grid<f64>, max_m: f64) -> RgbImage {
    RgbImage::from_fn(depth_m.width() as u32, depth_m.height() as u32, |x, y| {
        let d = depth_m[(x as usize, y as usize)];
        if !(d > 0.0) || !d.is_finite() {
            return NO_DEPTH;
        }
        let t = if max_m > 0.0 {
            (d / max_m).min(1.0)
        } else {
            1.0
        };
        let level = (245.0 - 185.0 * t).round() as u8;
        Rgb([level; 3])
    })
}

/// `img` scaled down (triangle filter, aspect ratio kept) to fit `max_w`×`max_h`; an image
/// that already fits is returned as it is.
pub fn fit_within(img: &RgbImage, max_w: u32, max_h: u32) -> RgbImage {
    if img.width() <= max_w && img.height() <= max_h {
        return img.clone();
    }
    let s = f64::min(
        f64::from(max_w) / f64::from(img.width()),
        f64::from(max_h) / f64::from(img.height()),
    );
    let w = ((f64::from(img.width()) * s).round() as u32).max(1);
    let h = ((f64::from(img.height()) * s).round() as u32).max(1);
    imageops::resize(img, w, h, imageops::FilterType::Triangle)
}

/// `v` with at most 2 decimals and no trailing zeros: `2`, `0.5`, `1.25`.
fn short_number(v: f64) -> String {
    let s = format!("{v:.2}");
    s.trim_end_matches('0').trim_end_matches('.').to_owned()
}

/// A legend strip `width` pixels wide: "roughness", the Turbo bar over `[0, max_m]` with a
/// tick and a label at each of `ticks_cm` (centimetres; ones outside the scale are left out,
/// and a label that would overlap the previous one is skipped), "cm", and a grey swatch
/// saying "no data". The bar's first column is the colour of 0 and its last that of `max_m`,
/// exactly as [`roughness_panel`] draws them.
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
/// categorical legend as the one legend of a [`contact_sheet`].
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
    use super::*;

    fn ink_pixels(img: &RgbImage) -> Vec<(u32, u32)> {
        img.enumerate_pixels()
            .filter(|(_, _, p)| **p == INK)
            .map(|(x, y, _)| (x, y))
            .collect()
    }

    #[test]
    fn text_pixels_land_where_drawn_and_only_there() {
        let mut img = RgbImage::from_pixel(40, 30, BACKGROUND);
        draw_text(&mut img, 10, 5, "I", 2, INK);
        // 'I' at scale 2: a vertical bar of rows 0..7 in column 2 (pixels 14..16), serifs in
        // columns 1 and 3 on rows 0 and 6.
        let ink = ink_pixels(&img);
        assert!(ink.contains(&(14, 5)) && ink.contains(&(15, 18)));
        assert!(ink.contains(&(12, 5)) && ink.contains(&(17, 17)));
        assert!(!ink.contains(&(14, 19)), "row 7 of 'I' is empty");
        let (w, h) = text_size("I", 2);
        assert!(ink
            .iter()
            .all(|&(x, y)| (10..10 + w).contains(&x) && (5..5 + h).contains(&y)));
        assert_eq!(
            ink.len(),
            (7 + 2 * 2) * 4,
            "a 7-pixel bar and 4 serif pixels, each 2×2"
        );
    }

    #[test]
    fn glyphs_differ_and_unknown_characters_draw_as_question_marks() {
        let draw = |s: &str| {
            let mut img = RgbImage::from_pixel(12, 16, BACKGROUND);
            draw_text(&mut img, 0, 0, s, 1, INK);
            ink_pixels(&img)
        };
        for (a, b) in [("0", "O"), ("1", "l"), ("5", "S"), ("c", "e"), ("m", "n")] {
            assert_ne!(draw(a), draw(b), "{a} and {b}");
        }
        assert_eq!(draw("é"), draw("?"));
        assert!(draw(" ").is_empty());
        assert!(FONT.iter().skip(1).all(|g| g.iter().any(|&c| c != 0)));
    }

    #[test]
    fn text_is_clipped_at_the_edges() {
        let mut img = RgbImage::from_pixel(8, 8, BACKGROUND);
        draw_text(&mut img, 5, 5, "WWW", 3, INK);
        assert!(!ink_pixels(&img).is_empty());
    }

    #[test]
    fn sheet_size_follows_panels_columns_and_legend() {
        let panel = |w, h| Panel::new("t", RgbImage::new(w, h));
        let panels = [panel(30, 20), panel(50, 10), panel(10, 40)];
        for (columns, (cols, rows)) in [(1, (1, 3)), (2, (2, 2)), (3, (3, 1)), (9, (3, 1))] {
            let sheet = contact_sheet(&panels, columns, None);
            let expected = (8 + cols * (50 + 8), 8 + rows * (TITLE_H + 40 + 8));
            assert_eq!(sheet.dimensions(), expected, "{columns} columns");
        }
        let legend = RgbImage::new(400, 30);
        let sheet = contact_sheet(&panels, 3, Some(&legend));
        assert_eq!(sheet.dimensions(), (416, 8 + TITLE_H + 48 + 38));
        let red = Rgb([255, 0, 0]);
        let one = [Panel::new("", RgbImage::from_pixel(100, 10, red))];
        let sheet = contact_sheet(&one, 1, Some(&legend));
        let row: Vec<_> = (0..416).map(|x| *sheet.get_pixel(x, 8 + TITLE_H)).collect();
        let left = row.iter().position(|p| *p == red);
        assert_eq!(
            left,
            Some((416 - 116) / 2 + 8),
            "the grid is centred over the legend"
        );
    }

    #[test]
    fn panels_are_centred_in_their_cells_under_their_titles() {
        let red = Rgb([255, 0, 0]);
        let panels = [
            Panel::new("big", RgbImage::from_pixel(40, 40, Rgb([0, 0, 255]))),
            Panel::new("small", RgbImage::from_pixel(10, 10, red)),
        ];
        let sheet = contact_sheet(&panels, 2, None);
        let (x0, y0) = (8 + 48 + 15, 8 + TITLE_H + 15);
        assert_eq!(*sheet.get_pixel(x0, y0), red);
        assert_eq!(*sheet.get_pixel(x0 + 9, y0 + 9), red);
        assert_eq!(*sheet.get_pixel(x0 - 1, y0), BACKGROUND);
        let title_ink = (8..8 + TITLE_H).any(|y| (56..104).any(|x| *sheet.get_pixel(x, y) == INK));
        assert!(title_ink, "the second panel's title is drawn above it");
    }

    #[test]
    fn long_titles_are_cut_to_the_cell() {
        let title = fit_text("a very long title indeed", 60, 2);
        assert!(
            title.ends_with("..") && text_size(&title, 2).0 <= 60,
            "{title}"
        );
        assert_eq!(fit_text("rgb", 60, 2), "rgb");
    }

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
    fn nan_renders_grey_that_turbo_never_takes() {
        let map = Grid::from_vec(3, 1, vec![f64::NAN, 0.02, f64::INFINITY]).unwrap();
        let img = roughness_panel(&map, 0.05);
        assert_eq!(*img.get_pixel(0, 0), NO_DATA);
        assert_eq!(*img.get_pixel(2, 0), NO_DATA);
        assert_eq!(img.get_pixel(1, 0).0, turbo(0.4));
        let distance = |a: [u8; 3], b: [u8; 3]| {
            a.iter()
                .zip(b)
                .map(|(&x, y)| i32::from(x).abs_diff(i32::from(y)))
                .max()
                .unwrap_or(0)
        };
        let nearest = (0..=1000)
            .map(|i| distance(turbo(f64::from(i) / 1000.0), NO_DATA.0))
            .min()
            .unwrap();
        assert!(nearest >= 40, "no-data grey is {nearest} from the scale");
    }

    #[test]
    fn depth_panel_marks_missing_depth_black_and_near_brighter() {
        let map = Grid::from_vec(3, 1, vec![0.0, 1.0, 4.0]).unwrap();
        let img = depth_panel(&map, 5.0);
        assert_eq!(*img.get_pixel(0, 0), NO_DEPTH);
        assert!(img.get_pixel(1, 0).0[0] > img.get_pixel(2, 0).0[0]);
        assert!(img.get_pixel(2, 0).0[0] > 40);
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

    #[test]
    fn fit_within_keeps_the_aspect_ratio() {
        let img = RgbImage::new(640, 480);
        assert_eq!(fit_within(&img, 320, 320).dimensions(), (320, 240));
        assert_eq!(fit_within(&img, 800, 800).dimensions(), (640, 480));
    }
}
