//! Colour-mapped roughness previews for people: the Turbo colour map and a legend strip with
//! the scale written on it (a built-in 3×5 pixel font, so no font files are needed).

use image::{Rgb, RgbImage};

use tre_core::geometry::Grid;

/// The Turbo colour map (Mikhailov 2019, polynomial fit) at `t` in [0, 1].
///
/// ```
/// let blue = tre_io::colormap::turbo(0.15);
/// let red = tre_io::colormap::turbo(1.0);
/// assert!(blue[2] > blue[0] && red[0] > red[2]);
/// ```
pub fn turbo(t: f64) -> [u8; 3] {
    let t = t.clamp(0.0, 1.0);
    let poly = |c: [f64; 6]| c[0] + t * (c[1] + t * (c[2] + t * (c[3] + t * (c[4] + t * c[5]))));
    let r = poly([
        0.13572138,
        4.61539260,
        -42.66032258,
        132.13108234,
        -152.94239396,
        59.28637943,
    ]);
    let g = poly([
        0.09140261,
        2.19418839,
        4.84296658,
        -14.18503333,
        4.27729857,
        2.82956604,
    ]);
    let b = poly([
        0.10667330,
        12.64194608,
        -60.58204836,
        110.36276771,
        -89.90310912,
        27.34824973,
    ]);
    [r, g, b].map(|c| (c.clamp(0.0, 1.0) * 255.0).round() as u8)
}

/// Colour of pixels without data.
const NO_DATA: [u8; 3] = [40, 40, 40];
/// Height of the legend strip, pixels.
const LEGEND_H: u32 = 22;

/// Renders roughness (metres, NaN: none) with Turbo over `[0, max_m]` and a legend strip below
/// that shows the colour bar with its scale in centimetres.
pub fn roughness_preview(roughness_m: &Grid<f64>, max_m: f64) -> RgbImage {
    let (w, h) = (roughness_m.width() as u32, roughness_m.height() as u32);
    let width = w.max(60);
    let mut img = RgbImage::from_pixel(width, h + LEGEND_H, Rgb([255, 255, 255]));
    image::imageops::replace(&mut img, &colourise(roughness_m, 0.0, max_m), 0, 0);
    draw_legend(&mut img, h, max_m);
    img
}

fn draw_legend(img: &mut RgbImage, top: u32, max_m: f64) {
    let width = img.width();
    let (bar_x0, bar_x1) = (4, width.saturating_sub(5));
    for x in bar_x0..=bar_x1 {
        let t = f64::from(x - bar_x0) / f64::from((bar_x1 - bar_x0).max(1));
        for y in top + 2..top + 9 {
            img.put_pixel(x, y, Rgb(turbo(t)));
        }
    }
    let max_cm = max_m * 100.0;
    draw_text(img, bar_x0, top + 12, "0");
    let mid = trim(max_cm / 2.0);
    draw_text(
        img,
        (bar_x0 + bar_x1) / 2 - text_width(&mid) / 2,
        top + 12,
        &mid,
    );
    let end = format!("{}cm", trim(max_cm));
    draw_text(
        img,
        bar_x1 + 1 - text_width(&end).min(bar_x1),
        top + 12,
        &end,
    );
}

fn trim(v: f64) -> String {
    let s = format!("{v:.2}");
    s.trim_end_matches('0').trim_end_matches('.').to_string()
}

fn text_width(s: &str) -> u32 {
    s.chars().count() as u32 * 4
}

/// 3×5 glyphs, one row per 3 bits (MSB left).
fn glyph(c: char) -> [u8; 5] {
    match c {
        '0' => [7, 5, 5, 5, 7],
        '1' => [2, 6, 2, 2, 7],
        '2' => [7, 1, 7, 4, 7],
        '3' => [7, 1, 7, 1, 7],
        '4' => [5, 5, 7, 1, 1],
        '5' => [7, 4, 7, 1, 7],
        '6' => [7, 4, 7, 5, 7],
        '7' => [7, 1, 1, 1, 1],
        '8' => [7, 5, 7, 5, 7],
        '9' => [7, 5, 7, 1, 7],
        '.' => [0, 0, 0, 0, 2],
        'c' => [0, 7, 4, 4, 7],
        'm' => [0, 7, 7, 5, 5],
        _ => [0; 5],
    }
}

fn draw_text(img: &mut RgbImage, x0: u32, y0: u32, s: &str) {
    for (i, c) in s.chars().enumerate() {
        for (row, bits) in glyph(c).iter().enumerate() {
            for col in 0..3u32 {
                let (x, y) = (x0 + i as u32 * 4 + col, y0 + row as u32);
                if bits & (4 >> col) != 0 && x < img.width() && y < img.height() {
                    img.put_pixel(x, y, Rgb([0, 0, 0]));
                }
            }
        }
    }
}

/// Turbo colours of a float map over `[lo, hi]` (non-finite: no-data grey).
pub fn colourise(map: &Grid<f64>, lo: f64, hi: f64) -> RgbImage {
    RgbImage::from_fn(map.width() as u32, map.height() as u32, |x, y| {
        let v = map[(x as usize, y as usize)];
        Rgb(if !v.is_finite() {
            NO_DATA
        } else {
            turbo((v - lo) / (hi - lo))
        })
    })
}

/// A distinct colour per label (0: black).
pub fn labels(map: &Grid<u32>) -> RgbImage {
    // Labels 0–6 (void and the natural categories) keep their colours; 7–20 are the indoor and
    // urban ones (docs/synth.md).
    const PALETTE: [[u8; 3]; 21] = [
        [0, 0, 0],
        [160, 160, 160],
        [60, 170, 60],
        [150, 120, 90],
        [110, 90, 160],
        [230, 200, 120],
        [220, 80, 60],
        [80, 160, 220],
        [190, 130, 60],
        [150, 60, 140],
        [240, 240, 240],
        [255, 160, 0],
        [255, 0, 200],
        [200, 170, 100],
        [100, 60, 30],
        [60, 60, 70],
        [200, 110, 100],
        [0, 200, 200],
        [120, 220, 120],
        [40, 80, 200],
        [255, 240, 0],
    ];
    RgbImage::from_fn(map.width() as u32, map.height() as u32, |x, y| {
        Rgb(PALETTE[map[(x as usize, y as usize)] as usize % PALETTE.len()])
    })
}

/// Colour of a three-state pixel in previews and on the demo page: traversable green, hazard
/// red, unknown grey-violet (distinct from both and from the roughness colour map's dark grey
/// for no data).
pub fn traversal_rgb(t: tre_core::roughness::traversal::Traversal) -> [u8; 3] {
    use tre_core::roughness::traversal::Traversal;
    match t {
        Traversal::Traversable => [44, 160, 44],
        Traversal::Hazard => [214, 39, 40],
        Traversal::Unknown => [150, 130, 190],
    }
}

/// Colour preview of a three-state map ([`traversal_rgb`]).
pub fn traversal_preview(map: &Grid<tre_core::roughness::traversal::Traversal>) -> RgbImage {
    RgbImage::from_fn(map.width() as u32, map.height() as u32, |x, y| {
        image::Rgb(traversal_rgb(map[(x as usize, y as usize)]))
    })
}
