//! Moving maps between the frame's size and the working size: RGB is filtered (it is only
//! appearance), everything geometric is sampled nearest-neighbour so that no value is ever a
//! blend of two surfaces across a depth discontinuity.

use std::borrow::Cow;

use image::RgbImage;
use rayon::prelude::*;

use tre_core::geometry::Grid;

/// `rgb` at `(width, height)`: unchanged when it already has that size, else resampled with a
/// triangle (bilinear) filter whose support widens with the shrink factor, so that shrinking
/// averages over each output pixel's source area instead of aliasing. The filter and its taps
/// are those of `image::imageops::resize` with `FilterType::Triangle` (columns first, f32,
/// rounded to the nearest byte); the passes run on precomputed taps, rows in parallel.
///
/// ```
/// use tre_pipeline::resize::resize_rgb;
/// let img = image::RgbImage::from_fn(8, 4, |x, _| image::Rgb([x as u8 * 10, 0, 255]));
/// let small = resize_rgb(&img, 4, 2);
/// assert_eq!(small.dimensions(), (4, 2));
/// assert_eq!(small.get_pixel(0, 0).0, [7, 0, 255]);
/// ```
pub fn resize_rgb(rgb: &RgbImage, width: usize, height: usize) -> Cow<'_, RgbImage> {
    let (w_in, h_in) = (rgb.width() as usize, rgb.height() as usize);
    if (w_in, h_in) == (width, height) {
        return Cow::Borrowed(rgb);
    }
    if w_in == 0 || h_in == 0 || width == 0 || height == 0 {
        return Cow::Owned(RgbImage::new(width as u32, height as u32));
    }
    let rows = Taps::triangle(h_in, height);
    let cols = Taps::triangle(w_in, width);
    let raw = rgb.as_raw();
    // Vertical pass: `height` rows of `w_in` pixels, f32.
    let mut tmp = vec![0f32; height * w_in * 3];
    tmp.par_chunks_mut(w_in * 3)
        .enumerate()
        .for_each(|(y, row)| {
            let (start, weights) = rows.of(y);
            for (k, &wt) in weights.iter().enumerate() {
                let src = &raw[(start + k) * w_in * 3..(start + k + 1) * w_in * 3];
                for (o, &v) in row.iter_mut().zip(src) {
                    *o += wt * f32::from(v);
                }
            }
        });
    // Horizontal pass, rounded to bytes.
    let mut out = vec![0u8; height * width * 3];
    out.par_chunks_mut(width * 3)
        .zip(tmp.par_chunks(w_in * 3))
        .for_each(|(row, src)| {
            for (x, px) in row.chunks_exact_mut(3).enumerate() {
                let (start, weights) = cols.of(x);
                let mut acc = [0f32; 3];
                for (k, &wt) in weights.iter().enumerate() {
                    let s = &src[(start + k) * 3..(start + k) * 3 + 3];
                    for c in 0..3 {
                        acc[c] += wt * s[c];
                    }
                }
                for c in 0..3 {
                    px[c] = acc[c].clamp(0.0, 255.0).round() as u8;
                }
            }
        });
    Cow::Owned(
        RgbImage::from_raw(width as u32, height as u32, out)
            .expect("buffer sized for the image; this is a bug"),
    )
}

/// Normalised filter taps of every output index along one axis.
struct Taps {
    /// First source index of each output index.
    start: Vec<usize>,
    /// Range of each output index's weights in `weights`.
    range: Vec<(usize, usize)>,
    weights: Vec<f32>,
}

impl Taps {
    /// Triangle-filter taps from `n_in` to `n_out`, as `image` computes them.
    fn triangle(n_in: usize, n_out: usize) -> Self {
        let ratio = n_in as f32 / n_out as f32;
        let sratio = ratio.max(1.0);
        let support = sratio;
        let mut taps = Self {
            start: Vec::with_capacity(n_out),
            range: Vec::with_capacity(n_out),
            weights: Vec::with_capacity(n_out * (2 * support.ceil() as usize + 2)),
        };
        for o in 0..n_out {
            let centre = (o as f32 + 0.5) * ratio;
            let left = ((centre - support).floor() as i64).clamp(0, n_in as i64 - 1) as usize;
            let right =
                ((centre + support).ceil() as i64).clamp(left as i64 + 1, n_in as i64) as usize;
            let centre = centre - 0.5;
            let first = taps.weights.len();
            let mut sum = 0.0;
            for i in left..right {
                let t = ((i as f32 - centre) / sratio).abs();
                let w = if t < 1.0 { 1.0 - t } else { 0.0 };
                taps.weights.push(w);
                sum += w;
            }
            if sum != 0.0 {
                for w in &mut taps.weights[first..] {
                    *w /= sum;
                }
            }
            taps.start.push(left);
            taps.range.push((first, taps.weights.len()));
        }
        taps
    }

    /// First source index and weights of output index `o`.
    fn of(&self, o: usize) -> (usize, &[f32]) {
        let (a, b) = self.range[o];
        (self.start[o], &self.weights[a..b])
    }
}

/// The source index that output index `i` of `n_out` samples among `n_in`: the pixel whose
/// area `[j, j + 1)` holds the output pixel's centre (on an edge between two, the later one).
///
/// ```
/// use tre_pipeline::resize::nearest_index;
/// assert_eq!(nearest_index(0, 4, 2), 1);
/// assert_eq!(nearest_index(1, 4, 2), 3);
/// assert_eq!(nearest_index(0, 3, 1), 1);
/// assert_eq!(nearest_index(5, 2, 6), 1);
/// ```
pub fn nearest_index(i: usize, n_in: usize, n_out: usize) -> usize {
    let centre = (i as f64 + 0.5) * n_in as f64 / n_out as f64;
    (centre as usize).min(n_in.saturating_sub(1))
}

/// Nearest-neighbour resampling of `src` into `out` (whose size is the target), rows in
/// parallel.
///
/// ```
/// use tre_core::geometry::Grid;
/// use tre_pipeline::resize::resize_nearest_into;
/// let src = Grid::from_fn(2, 1, |x, _| x as f64);
/// let mut out = Grid::new(4, 2, 0.0);
/// resize_nearest_into(&src, &mut out);
/// assert_eq!(out.row(1), &[0.0, 0.0, 1.0, 1.0]);
/// ```
pub fn resize_nearest_into<T: Clone + Send + Sync>(src: &Grid<T>, out: &mut Grid<T>) {
    let (w_in, h_in) = src.size();
    let (w_out, h_out) = out.size();
    if w_in == 0 || h_in == 0 {
        return;
    }
    out.as_mut_slice()
        .par_chunks_mut(w_out.max(1))
        .enumerate()
        .for_each(|(y, row)| {
            let src_row = src.row(nearest_index(y, h_in, h_out));
            for (x, v) in row.iter_mut().enumerate() {
                v.clone_from(&src_row[nearest_index(x, w_in, w_out)]);
            }
        });
}

/// `src` at `(width, height)` by nearest neighbour (a copy when the size is the same); `fill`
/// only shows where `src` is empty.
pub fn resize_nearest<T: Clone + Send + Sync>(
    src: &Grid<T>,
    width: usize,
    height: usize,
    fill: T,
) -> Grid<T> {
    let mut out = Grid::default();
    resize_nearest_reusing(src, (width, height), fill, &mut out);
    out
}

/// [`resize_nearest`] into `out`, which takes the size `(width, height)` and keeps its buffer
/// (a copy into it when the size is the same).
///
/// ```
/// use tre_core::geometry::Grid;
/// use tre_pipeline::resize::resize_nearest_reusing;
/// let mut out = Grid::new(8, 8, 9.0);
/// resize_nearest_reusing(&Grid::from_fn(2, 1, |x, _| x as f64), (4, 1), f64::NAN, &mut out);
/// assert_eq!(out.row(0), &[0.0, 0.0, 1.0, 1.0]);
/// ```
pub fn resize_nearest_reusing<T: Clone + Send + Sync>(
    src: &Grid<T>,
    (width, height): (usize, usize),
    fill: T,
    out: &mut Grid<T>,
) {
    if src.size() == (width, height) {
        out.clone_from(src);
    } else {
        out.reset(width, height, fill);
        resize_nearest_into(src, out);
    }
}

#[cfg(test)]
mod rgb_tests {
    use super::*;

    #[test]
    fn matches_image_triangle_resize_within_one_level() {
        let img = RgbImage::from_fn(640, 480, |x, y| {
            image::Rgb([
                (x * 7 % 251) as u8,
                (y * 13 % 241) as u8,
                ((x * y) % 239) as u8,
            ])
        });
        for (w, h) in [(256, 192), (80, 256), (1000, 700), (3, 2)] {
            let ours = resize_rgb(&img, w, h);
            let theirs = image::imageops::resize(
                &img,
                w as u32,
                h as u32,
                image::imageops::FilterType::Triangle,
            );
            let worst = ours
                .as_raw()
                .iter()
                .zip(theirs.as_raw())
                .map(|(&a, &b)| a.abs_diff(b))
                .max()
                .unwrap_or(0);
            assert!(worst <= 1, "{w}×{h}: differs by {worst}");
        }
    }
}
