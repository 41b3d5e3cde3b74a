//! The map's pictures for people: one panel per layer, every panel cropped to the same box (the
//! seen cells and the camera's positions, plus a margin), each cell a square of whole pixels,
//! the camera's path drawn over it (a ring at its start, an arrow at its last pose pointing
//! where the camera looked), a metric scale bar and the layer's colour bar or states below;
//! the sheet of all panels and a view per layer, each with a header and the symbols' key.

use image::{imageops, Rgb, RgbImage};
use tre_core::geometry::Grid;

use super::style::{Style, NOT_SEEN};
use super::{CameraMark, MapWindow};
use crate::sheet::{self, draw_text, fill, tile, wrap_text, BACKGROUND, INK};

mod keys;

use keys::{key_strip, legend_strip, scale_bar};

/// Font scale of the pictures' text.
pub(super) const TEXT: u32 = 2;
/// Height of a line of text, pixels.
pub(super) const LINE_H: u32 = sheet::GLYPH_H * TEXT + 4;
/// Gap between the parts of a panel, pixels.
pub(super) const GAP: u32 = 8;
/// Least width of a panel, pixels (room for a colour bar and its labels).
const MIN_PANEL_W: u32 = 320;
/// The longer side of the cropped map is scaled up towards this many pixels (whole pixels a
/// cell, 1 to 8).
const TARGET_MAP_PX: u32 = 480;
/// Margin around the seen cells, metres.
const CROP_MARGIN_M: f64 = 0.2;
/// Colour of the frame around each map.
const FRAME: Rgb<u8> = Rgb([120, 120, 120]);
/// Colour around the camera's path and symbols.
pub(super) const HALO: Rgb<u8> = Rgb([255, 255, 255]);

/// The cells shown: columns `c0..c0 + w`, rows `r0..r0 + h` of the window, each `px` pixels
/// square.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) struct Crop {
    /// First column.
    pub(super) c0: usize,
    /// First row.
    pub(super) r0: usize,
    /// Columns shown.
    pub(super) w: usize,
    /// Rows shown.
    pub(super) h: usize,
    /// Pixels a cell.
    pub(super) px: u32,
}

/// Where the cells and the camera lie: the window and the crop.
#[derive(Debug, Clone, Copy)]
pub(super) struct Geometry<'a> {
    window: &'a MapWindow,
    crop: Crop,
}

impl Geometry<'_> {
    /// The pixel of the map-frame point (`x_m`, `y_m`) in a cropped map image.
    fn pixel(&self, x_m: f64, y_m: f64) -> sheet::Point {
        let (w, c) = (self.window, self.crop);
        let col = x_m / w.cell_m - w.origin.0 as f64 - c.c0 as f64;
        let row = (w.origin.1 + w.side as i64) as f64 - y_m / w.cell_m - c.r0 as f64;
        (col * f64::from(c.px), row * f64::from(c.px))
    }

    /// Pixels a metre.
    pub(super) fn px_per_m(&self) -> f64 {
        f64::from(self.crop.px) / self.window.cell_m
    }
}

/// One layer to draw: its name, its stored unit and its cells (the window's layout).
#[derive(Debug, Clone, Copy)]
pub(super) struct LayerRef<'a> {
    /// Name.
    pub(super) name: &'a str,
    /// Stored unit.
    pub(super) unit: &'a str,
    /// Cells.
    pub(super) grid: &'a Grid<f32>,
}

/// The sheet of every layer, and each layer's view with its name.
#[derive(Debug, Clone)]
pub(super) struct Pictures {
    /// The cells shown.
    pub(super) crop: Crop,
    /// All panels in a grid, under the header, over the key.
    pub(super) sheet: RgbImage,
    /// One picture per layer: header, panel, key.
    pub(super) views: Vec<(String, RgbImage)>,
}

/// The pictures of `layers` in `window`, with `trajectory` drawn; `frames` fused (for the
/// header). A cell is seen when the `count` layer is above 0 (without one: when any layer is
/// finite there).
pub(super) fn pictures(
    layers: &[LayerRef<'_>],
    window: &MapWindow,
    trajectory: &[CameraMark],
    frames: usize,
) -> Pictures {
    let seen = seen_cells(layers, window.side);
    let crop = crop(&seen, window, trajectory);
    let geo = Geometry { window, crop };
    let styles: Vec<Style> = layers.iter().map(|l| style(l, &seen)).collect();
    let width = panel_width(&styles, crop);
    let title_lines = styles
        .iter()
        .map(|s| wrap_text(&s.title, width, TEXT).len())
        .max()
        .unwrap_or(1);
    let panels: Vec<RgbImage> = layers
        .iter()
        .zip(&styles)
        .map(|(l, s)| panel(l.grid, s, &seen, geo, trajectory, (width, title_lines)))
        .collect();
    let columns = columns(
        panels.len(),
        width,
        panels.first().map_or(1, RgbImage::height),
    );
    let grid = tile(&panels, columns);
    let text = header(window, crop, frames);
    let with_trajectory = !trajectory.is_empty();
    let sheet = sheet::stack(&[
        text_strip(&text, grid.width()),
        grid,
        key_strip(grid_width(columns, width), with_trajectory),
    ]);
    let views = layers
        .iter()
        .zip(panels)
        .map(|(l, p)| {
            let framed = tile(&[p], 1);
            let view = sheet::stack(&[
                text_strip(&text, framed.width()),
                framed,
                key_strip(width, with_trajectory),
            ]);
            (l.name.to_owned(), view)
        })
        .collect();
    Pictures { crop, sheet, views }
}

/// Width of a grid of `columns` panels `width` wide, as [`tile`] lays them.
fn grid_width(columns: usize, width: u32) -> u32 {
    GAP + columns as u32 * (width + GAP)
}

/// The columns that bring a sheet of `n` panels of `w`×`h` closest to 7:5, each empty place
/// in the last row counting as much as a 15% difference in aspect.
fn columns(n: usize, w: u32, h: u32) -> usize {
    let cost = |c: usize| {
        let rows = n.div_ceil(c);
        let aspect = (c as f64 * f64::from(w)) / (rows as f64 * f64::from(h.max(1)));
        (aspect / 1.4).ln().abs() + 0.15 * (rows * c - n) as f64
    };
    (1..=n.max(1))
        .min_by(|&a, &b| cost(a).total_cmp(&cost(b)))
        .unwrap_or(1)
}

/// Which cells of a `side`×`side` window were seen.
fn seen_cells(layers: &[LayerRef<'_>], side: usize) -> Vec<bool> {
    match layers.iter().find(|l| l.name == "count") {
        Some(count) => count.grid.as_slice().iter().map(|&c| c > 0.0).collect(),
        None => (0..side * side)
            .map(|i| layers.iter().any(|l| l.grid.as_slice()[i].is_finite()))
            .collect(),
    }
}

/// The style of a layer from the values of its seen cells.
fn style(l: &LayerRef<'_>, seen: &[bool]) -> Style {
    let values: Vec<f64> = l
        .grid
        .as_slice()
        .iter()
        .zip(seen)
        .filter(|(_, &s)| s)
        .map(|(&v, _)| f64::from(v))
        .collect();
    Style::of(l.name, l.unit, &values)
}

/// The box of the seen cells and of the camera's positions in the window, grown by
/// [`CROP_MARGIN_M`] and clamped to the window (nothing seen: the whole window), and the
/// pixels a cell that bring its longer side near [`TARGET_MAP_PX`].
pub(super) fn crop(seen: &[bool], window: &MapWindow, trajectory: &[CameraMark]) -> Crop {
    let side = window.side;
    let mut cells: Vec<(usize, usize)> = seen
        .iter()
        .enumerate()
        .filter(|(_, &s)| s)
        .map(|(i, _)| (i % side, i / side))
        .collect();
    let whole = Geometry {
        window,
        crop: Crop {
            c0: 0,
            r0: 0,
            w: side,
            h: side,
            px: 1,
        },
    };
    for m in trajectory {
        let (c, r) = whole.pixel(m.x_m, m.y_m);
        if (0.0..side as f64).contains(&c) && (0.0..side as f64).contains(&r) {
            cells.push((c as usize, r as usize));
        }
    }
    let margin = (CROP_MARGIN_M / window.cell_m).ceil() as usize;
    let span = |f: fn(&(usize, usize)) -> usize| {
        let lo = cells.iter().map(f).min().unwrap_or(0);
        let hi = cells.iter().map(f).max().unwrap_or(side.saturating_sub(1));
        let lo = lo.saturating_sub(margin);
        (lo, (hi + margin).min(side.saturating_sub(1)) + 1 - lo)
    };
    let ((c0, w), (r0, h)) = (span(|c| c.0), span(|c| c.1));
    let longer = w.max(h).max(1) as u32;
    let px = (TARGET_MAP_PX / longer).clamp(1, 8);
    Crop { c0, r0, w, h, px }
}

/// The width of every panel: the cropped map, the least width, and the widest word of a title.
fn panel_width(styles: &[Style], crop: Crop) -> u32 {
    let words = styles
        .iter()
        .map(|s| sheet::widest_word(&s.title, TEXT))
        .max()
        .unwrap_or(0);
    (crop.w as u32 * crop.px + 2).max(MIN_PANEL_W).max(words)
}

/// One layer's panel, `layout.0` wide: its title (in `layout.1` lines), the cropped map with
/// the camera's path, the scale bar and its colour bar or states.
fn panel(
    grid: &Grid<f32>,
    style: &Style,
    seen: &[bool],
    geo: Geometry<'_>,
    trajectory: &[CameraMark],
    (width, title_lines): (u32, usize),
) -> RgbImage {
    let mut map = map_image(grid, style, seen, geo.crop);
    keys::draw_trajectory(&mut map, trajectory, |m| geo.pixel(m.x_m, m.y_m));
    let bar = scale_bar(geo.px_per_m(), map.width(), width);
    let legend = legend_strip(style, width);
    let map_top = title_lines as u32 * LINE_H + GAP / 2;
    let height = map_top + map.height() + 2 + GAP + bar.height() + legend.height();
    let mut img = RgbImage::from_pixel(width, height, BACKGROUND);
    for (k, line) in wrap_text(&style.title, width, TEXT).iter().enumerate() {
        draw_text(&mut img, 0, k as u32 * LINE_H, line, TEXT, INK);
    }
    let x = (width - map.width() - 2) / 2;
    fill(
        &mut img,
        x,
        map_top,
        map.width() + 2,
        map.height() + 2,
        FRAME,
    );
    imageops::replace(&mut img, &map, i64::from(x + 1), i64::from(map_top + 1));
    let y = map_top + map.height() + 2 + GAP;
    imageops::replace(&mut img, &bar, 0, i64::from(y));
    imageops::replace(&mut img, &legend, 0, i64::from(y + bar.height()));
    img
}

/// The cropped cells of `grid` in `style`'s colours, each a `crop.px` square; cells never
/// seen in [`NOT_SEEN`].
fn map_image(grid: &Grid<f32>, style: &Style, seen: &[bool], crop: Crop) -> RgbImage {
    let side = grid.width();
    let mut img = RgbImage::new(crop.w as u32 * crop.px, crop.h as u32 * crop.px);
    for r in 0..crop.h {
        for c in 0..crop.w {
            let (col, row) = (crop.c0 + c, crop.r0 + r);
            let colour = if seen[row * side + col] {
                style.colour(f64::from(grid[(col, row)]))
            } else {
                NOT_SEEN
            };
            let (x, y) = (c as u32 * crop.px, r as u32 * crop.px);
            fill(&mut img, x, y, crop.px, crop.px, colour);
        }
    }
    img
}

/// What the pictures show, in words.
fn header(window: &MapWindow, crop: Crop, frames: usize) -> String {
    let m = |cells: usize| cells as f64 * window.cell_m;
    let side = m(window.side);
    let cell_cm = (window.cell_m * 1000.0).round() / 10.0;
    format!(
        "{:.1} x {:.1} m shown of the {side:.1} x {side:.1} m window, {cell_cm} cm cells, \
         {frames} frames fused; looking down, x right, y up",
        m(crop.w),
        m(crop.h),
    )
}

/// `text` wrapped to `width` on the background, one line under another.
fn text_strip(text: &str, width: u32) -> RgbImage {
    let lines = wrap_text(text, width.saturating_sub(2 * GAP), TEXT);
    let w = lines
        .iter()
        .map(|l| sheet::text_size(l, TEXT).0)
        .max()
        .unwrap_or(0)
        .max(width.saturating_sub(2 * GAP));
    let mut img = RgbImage::from_pixel(w + 2 * GAP, GAP + lines.len() as u32 * LINE_H, BACKGROUND);
    for (k, line) in lines.iter().enumerate() {
        draw_text(&mut img, GAP, GAP + k as u32 * LINE_H, line, TEXT, INK);
    }
    img
}

#[cfg(test)]
mod tests {
    use super::*;

    /// An 8 m window of 4 cm cells whose lower-left cell is the world's (−100, −100).
    fn window() -> MapWindow {
        MapWindow {
            cell_m: 0.04,
            side: 200,
            origin: (-100, -100),
            map_from_world: [1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0],
            memory_bytes: None,
        }
    }

    /// `count`, `elevation` and `traversal` of a window seen in columns `cols` and rows `rows`.
    fn seen_box(cols: std::ops::Range<usize>, rows: std::ops::Range<usize>) -> [Grid<f32>; 3] {
        let inside = |c: usize, r: usize| cols.contains(&c) && rows.contains(&r);
        let count = Grid::from_fn(200, 200, |c, r| if inside(c, r) { 4.0 } else { 0.0 });
        let elevation = Grid::from_fn(200, 200, |c, r| {
            if inside(c, r) {
                0.01 * c as f32
            } else {
                f32::NAN
            }
        });
        let traversal = Grid::from_fn(200, 200, |c, r| if inside(c, r) { 1.0 } else { 0.0 });
        [count, elevation, traversal]
    }

    fn refs(grids: &[Grid<f32>; 3]) -> Vec<LayerRef<'_>> {
        let names = [
            ("count", "measurements"),
            ("elevation", "m"),
            ("traversal", ""),
        ];
        names
            .iter()
            .zip(grids)
            .map(|(&(name, unit), grid)| LayerRef { name, unit, grid })
            .collect()
    }

    /// The size of the box of pixels in the map frame's colour.
    fn frame_size(img: &RgbImage) -> (u32, u32) {
        let frame: Vec<(u32, u32)> = img
            .enumerate_pixels()
            .filter(|(_, _, p)| **p == FRAME)
            .map(|(x, y, _)| (x, y))
            .collect();
        let span = |f: fn(&(u32, u32)) -> u32| {
            frame.iter().map(f).max().unwrap() - frame.iter().map(f).min().unwrap() + 1
        };
        (span(|p| p.0), span(|p| p.1))
    }

    #[test]
    fn the_crop_is_the_seen_box_plus_a_margin() {
        let grids = seen_box(50..75, 120..130);
        let seen = seen_cells(&refs(&grids), 200);
        let c = crop(&seen, &window(), &[]);
        // 0.2 m is 5 cells each side; 35 columns bring 13 pixels a cell, at most 8.
        let expected = Crop {
            c0: 45,
            r0: 115,
            w: 35,
            h: 20,
            px: 8,
        };
        assert_eq!(c, expected);
        let all = crop(&[false; 200 * 200], &window(), &[]);
        assert_eq!((all.c0, all.r0, all.w, all.h, all.px), (0, 0, 200, 200, 2));
        let corner = seen_box(0..3, 197..200);
        let c = crop(&seen_cells(&refs(&corner), 200), &window(), &[]);
        assert_eq!(
            (c.c0, c.r0, c.w, c.h),
            (0, 192, 8, 8),
            "clamped to the window"
        );
    }

    #[test]
    fn the_crop_holds_the_cameras_positions_in_the_window() {
        let grids = seen_box(50..75, 120..130);
        let seen = seen_cells(&refs(&grids), 200);
        // Column 100 spans x in [0, 0.04); row 60 spans y in [(−100 + 199 − 60)·0.04, +0.04).
        let mark = |x_m, y_m| CameraMark {
            x_m,
            y_m,
            heading_rad: 0.0,
        };
        let c = crop(&seen, &window(), &[mark(0.02, 1.57), mark(50.0, 0.0)]);
        assert_eq!((c.c0, c.w), (45, 105 - 45 + 1));
        assert_eq!((c.r0, c.h), (55, 134 - 55 + 1));
    }

    #[test]
    fn a_small_seen_area_makes_panels_of_its_size_not_the_windows() {
        let small = seen_box(50..75, 120..130);
        let trajectory = [
            CameraMark {
                x_m: -1.9,
                y_m: -0.9,
                heading_rad: 0.5,
            },
            CameraMark {
                x_m: -1.4,
                y_m: -0.8,
                heading_rad: 1.0,
            },
        ];
        let p = pictures(&refs(&small), &window(), &trajectory, 2);
        assert_eq!(p.views.len(), 3);
        for (name, view) in &p.views {
            assert_eq!(frame_size(view), (35 * 8 + 2, 20 * 8 + 2), "{name}");
        }
        let full = seen_box(0..200, 0..200);
        let whole = pictures(&refs(&full), &window(), &[], 2);
        assert_eq!(frame_size(&whole.views[0].1), (402, 402));
        let area = |img: &RgbImage| f64::from(img.width()) * f64::from(img.height());
        let (small_sheet, whole_sheet) = (area(&p.sheet), area(&whole.sheet));
        assert!(
            small_sheet < 0.7 * whole_sheet,
            "{small_sheet} against {whole_sheet}"
        );
        // The path is drawn in the cropped map: ink where the camera went.
        let view = &p.views[0].1;
        let ink = view.pixels().filter(|p| **p == INK).count();
        let plain = pictures(&refs(&small), &window(), &[], 2);
        let plain_ink = plain.views[0].1.pixels().filter(|p| **p == INK).count();
        assert!(ink > plain_ink + 100, "{ink} against {plain_ink}");
    }

    #[test]
    fn titles_are_whole_and_the_sheet_fits_its_panels() {
        let grids = seen_box(50..75, 120..130);
        let p = pictures(&refs(&grids), &window(), &[], 0);
        let widest = ["count (measurements)", "elevation (cm)"]
            .iter()
            .map(|t| sheet::text_size(t, TEXT).0)
            .max()
            .unwrap();
        assert!(p.views.iter().all(|(_, v)| v.width() >= widest));
        assert!(p.views.iter().all(|(_, v)| v.width() <= p.sheet.width()));
        assert_eq!(columns(9, 430, 400), 3);
        assert_eq!(columns(1, 430, 400), 1);
    }
}
