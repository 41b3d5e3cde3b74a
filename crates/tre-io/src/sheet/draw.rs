//! Shapes for pictures drawn over images: thick line segments, discs, filled triangles (all at
//! sub-pixel positions, clipped to the image), text wrapped to a width, and images tiled in a
//! grid.

use image::{imageops, Rgb, RgbImage};

use super::font::text_size;
use super::{BACKGROUND, MARGIN};

/// A point in pixel coordinates (x right, y down; pixel (i, j) covers [i, i + 1) × [j, j + 1)).
pub type Point = (f64, f64);

/// Sets every pixel whose centre satisfies `inside` within the box `lo`..`hi` (clipped to the
/// image) to `colour`.
fn paint(
    img: &mut RgbImage,
    lo: Point,
    hi: Point,
    colour: Rgb<u8>,
    inside: impl Fn(Point) -> bool,
) {
    let clamp_x = |v: f64| v.clamp(0.0, f64::from(img.width())) as u32;
    let clamp_y = |v: f64| v.clamp(0.0, f64::from(img.height())) as u32;
    let (x0, x1) = (clamp_x(lo.0.floor()), clamp_x(hi.0.ceil() + 1.0));
    let (y0, y1) = (clamp_y(lo.1.floor()), clamp_y(hi.1.ceil() + 1.0));
    for y in y0..y1 {
        for x in x0..x1 {
            if inside((f64::from(x) + 0.5, f64::from(y) + 0.5)) {
                img.put_pixel(x, y, colour);
            }
        }
    }
}

/// The segment `a`–`b` drawn `radius` pixels to each side (round ends) in `colour`.
pub fn thick_line(img: &mut RgbImage, a: Point, b: Point, radius: f64, colour: Rgb<u8>) {
    let lo = (a.0.min(b.0) - radius, a.1.min(b.1) - radius);
    let hi = (a.0.max(b.0) + radius, a.1.max(b.1) + radius);
    let (dx, dy) = (b.0 - a.0, b.1 - a.1);
    let len2 = dx * dx + dy * dy;
    paint(img, lo, hi, colour, |p| {
        let t = if len2 > 0.0 {
            (((p.0 - a.0) * dx + (p.1 - a.1) * dy) / len2).clamp(0.0, 1.0)
        } else {
            0.0
        };
        let (ex, ey) = (p.0 - a.0 - t * dx, p.1 - a.1 - t * dy);
        ex * ex + ey * ey <= radius * radius
    });
}

/// A filled disc of `radius` pixels centred at `c`.
pub fn disc(img: &mut RgbImage, c: Point, radius: f64, colour: Rgb<u8>) {
    thick_line(img, c, c, radius, colour);
}

/// The filled triangle `t` (either winding).
pub fn triangle(img: &mut RgbImage, t: [Point; 3], colour: Rgb<u8>) {
    let lo = (
        t[0].0.min(t[1].0).min(t[2].0),
        t[0].1.min(t[1].1).min(t[2].1),
    );
    let hi = (
        t[0].0.max(t[1].0).max(t[2].0),
        t[0].1.max(t[1].1).max(t[2].1),
    );
    let edge = |a: Point, b: Point, p: Point| (b.0 - a.0) * (p.1 - a.1) - (b.1 - a.1) * (p.0 - a.0);
    paint(img, lo, hi, colour, |p| {
        let e = [
            edge(t[0], t[1], p),
            edge(t[1], t[2], p),
            edge(t[2], t[0], p),
        ];
        e.iter().all(|&v| v >= 0.0) || e.iter().all(|&v| v <= 0.0)
    });
}

/// An arrow head at `tip` pointing along `dir` (need not be unit length), `len` pixels long, in
/// `colour` with a `halo`-coloured outline two pixels wide.
pub fn arrow_head(
    img: &mut RgbImage,
    tip: Point,
    dir: Point,
    len: f64,
    colour: Rgb<u8>,
    halo: Rgb<u8>,
) {
    let norm = dir.0.hypot(dir.1);
    let (ux, uy) = if norm > 0.0 {
        (dir.0 / norm, dir.1 / norm)
    } else {
        (1.0, 0.0)
    };
    let back = (tip.0 - len * ux, tip.1 - len * uy);
    let half = len * 0.45;
    let t = [
        tip,
        (back.0 - half * uy, back.1 + half * ux),
        (back.0 + half * uy, back.1 - half * ux),
    ];
    for (a, b) in [(t[0], t[1]), (t[1], t[2]), (t[2], t[0])] {
        thick_line(img, a, b, 2.0, halo);
    }
    triangle(img, t, colour);
}

/// `text` broken at spaces into lines of at most `max_w` pixels at `scale`; a word wider
/// than `max_w` stays whole on a line of its own (see [`widest_word`]). Never cuts a word.
pub fn wrap_text(text: &str, max_w: u32, scale: u32) -> Vec<String> {
    let mut lines: Vec<String> = Vec::new();
    for word in text.split_whitespace() {
        match lines.last_mut() {
            Some(line) if text_size(&format!("{line} {word}"), scale).0 <= max_w => {
                line.push(' ');
                line.push_str(word);
            }
            _ => lines.push(word.to_owned()),
        }
    }
    lines
}

/// Width of the widest word of `text` at `scale`, pixels: the least width [`wrap_text`] fits.
pub fn widest_word(text: &str, scale: u32) -> u32 {
    text.split_whitespace()
        .map(|w| text_size(w, scale).0)
        .max()
        .unwrap_or(0)
}

/// `images` in a grid of `columns`, row by row, each at the top-left of a cell as large as the
/// largest, 8 pixels apart and from the edges, on the background.
pub fn tile(images: &[RgbImage], columns: usize) -> RgbImage {
    let columns = columns.clamp(1, images.len().max(1)) as u32;
    let rows = (images.len() as u32).div_ceil(columns);
    let cell_w = images.iter().map(RgbImage::width).max().unwrap_or(0);
    let cell_h = images.iter().map(RgbImage::height).max().unwrap_or(0);
    let width = MARGIN + columns * (cell_w + MARGIN);
    let height = MARGIN + rows * (cell_h + MARGIN);
    let mut out = RgbImage::from_pixel(width, height, BACKGROUND);
    for (i, img) in images.iter().enumerate() {
        let (col, row) = (i as u32 % columns, i as u32 / columns);
        let x = MARGIN + col * (cell_w + MARGIN);
        let y = MARGIN + row * (cell_h + MARGIN);
        imageops::replace(&mut out, img, i64::from(x), i64::from(y));
    }
    out
}

#[cfg(test)]
mod tests {
    use super::super::{ink_pixels, INK};
    use super::*;

    #[test]
    fn a_line_covers_its_segment_and_is_clipped() {
        let mut img = RgbImage::from_pixel(20, 10, BACKGROUND);
        thick_line(&mut img, (-5.0, 5.0), (30.0, 5.0), 1.0, INK);
        let ink = ink_pixels(&img);
        assert_eq!(ink.len(), 2 * 20, "rows 4 and 5, every column");
        assert!(ink.iter().all(|&(_, y)| y == 4 || y == 5));
    }

    #[test]
    fn a_triangle_fills_its_inside_either_way_round() {
        let t = [(0.0, 0.0), (10.0, 0.0), (0.0, 10.0)];
        let count = |t: [Point; 3]| {
            let mut img = RgbImage::from_pixel(12, 12, BACKGROUND);
            triangle(&mut img, t, INK);
            ink_pixels(&img).len()
        };
        assert_eq!(count(t), count([t[0], t[2], t[1]]));
        assert!((45..=55).contains(&count(t)), "{}", count(t));
    }

    #[test]
    fn an_arrow_points_along_its_direction() {
        let mut img = RgbImage::from_pixel(40, 40, BACKGROUND);
        arrow_head(
            &mut img,
            (30.0, 20.0),
            (1.0, 0.0),
            14.0,
            INK,
            Rgb([255, 255, 0]),
        );
        let ink = ink_pixels(&img);
        let right = ink.iter().filter(|&&(x, _)| x >= 23).count();
        let left = ink.iter().filter(|&&(x, _)| x < 23).count();
        assert!(
            left > right,
            "the wide base is behind the tip: {left} {right}"
        );
        assert!(ink.iter().all(|&(x, _)| (15..=30).contains(&x)));
    }

    #[test]
    fn wrapping_keeps_every_word_whole() {
        let lines = wrap_text("count (measurements)", 150, 2);
        assert_eq!(lines, ["count", "(measurements)"]);
        assert_eq!(wrap_text("slope (degrees)", 400, 2), ["slope (degrees)"]);
        assert_eq!(
            widest_word("count (measurements)", 2),
            text_size("(measurements)", 2).0
        );
        assert!(wrap_text("", 100, 2).is_empty());
    }

    #[test]
    fn tiles_are_placed_row_by_row() {
        let red = Rgb([255, 0, 0]);
        let imgs = [
            RgbImage::new(10, 5),
            RgbImage::new(4, 8),
            RgbImage::from_pixel(3, 3, red),
        ];
        let out = tile(&imgs, 2);
        assert_eq!(out.dimensions(), (8 + 2 * 18, 8 + 2 * 16));
        assert_eq!(*out.get_pixel(8, 8 + 16), red);
    }
}
