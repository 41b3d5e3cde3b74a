//! Moving maps between the frame's size and the working size: RGB is filtered (it is only
//! appearance), everything geometric is sampled nearest-neighbour so that no value is ever a
//! blend of two surfaces across a depth discontinuity.

use std::borrow::Cow;

use image::imageops::{self, FilterType};
use image::RgbImage;
use rayon::prelude::*;

use crate::geometry::Grid;

/// `rgb` at `(width, height)`: unchanged when it already has that size, else resampled with a
/// triangle (bilinear) filter whose support widens with the shrink factor, so that shrinking
/// averages over each output pixel's source area instead of aliasing.
pub fn resize_rgb(rgb: &RgbImage, width: usize, height: usize) -> Cow<'_, RgbImage> {
    if (rgb.width() as usize, rgb.height() as usize) == (width, height) {
        return Cow::Borrowed(rgb);
    }
    Cow::Owned(imageops::resize(
        rgb,
        width as u32,
        height as u32,
        FilterType::Triangle,
    ))
}

/// The source index that output index `i` of `n_out` samples among `n_in`: the pixel whose
/// area `[j, j + 1)` holds the output pixel's centre (on an edge between two, the later one).
///
/// ```
/// use tre::pipeline::resize::nearest_index;
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
/// use tre::geometry::Grid;
/// use tre::pipeline::resize::resize_nearest_into;
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
    if src.size() == (width, height) {
        return src.clone();
    }
    let mut out = Grid::new(width, height, fill);
    resize_nearest_into(src, &mut out);
    out
}
