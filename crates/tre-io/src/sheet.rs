//! Contact sheets for people: titled panels in a grid, roughness maps in one shared Turbo scale,
//! a colour-bar or categorical legend (`legend.rs`), the 5×8 bitmap font that writes
//! their text (`font.rs`), and shapes, wrapped text and tiling for drawn pictures (`draw.rs`).
//!
//! A benchmark writes one sheet per frame ("RGB | spec | rgb | rgbd | geometric"): every
//! roughness panel is drawn by [`roughness_panel`] with the same `max_m`, so equal colours mean
//! equal roughness across panels, and [`colour_bar_legend`] states that scale below the grid.

use image::{imageops, Rgb, RgbImage};

use super::colormap::turbo;
use tre_core::geometry::Grid;

mod draw;
mod font;
mod legend;

pub use draw::{arrow_head, disc, thick_line, tile, triangle, widest_word, wrap_text, Point};
pub use font::{draw_text, fill, text_size, ADVANCE, GLYPH_H, GLYPH_W};
pub use legend::{categorical_legend, colour_bar_legend, stack};

use font::fit_text;

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

/// The pixels of `img` in [`INK`], for the tests of drawing.
#[cfg(test)]
fn ink_pixels(img: &RgbImage) -> Vec<(u32, u32)> {
    img.enumerate_pixels()
        .filter(|(_, _, p)| **p == INK)
        .map(|(x, y, _)| (x, y))
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

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
    fn fit_within_keeps_the_aspect_ratio() {
        let img = RgbImage::new(640, 480);
        assert_eq!(fit_within(&img, 320, 320).dimensions(), (320, 240));
        assert_eq!(fit_within(&img, 800, 800).dimensions(), (640, 480));
    }
}
