//! Grids ↔ NCHW float32 tensors (N = 1) in the layout the models expect: RGB in [0, 1],
//! points in metres with 0 and `valid = 0` where there is no point (NaN cannot flow through a
//! network), normals 0 where there is none. Tensors are caller-owned buffers, reused across
//! frames, filled plane by plane with rows in parallel.

use image::RgbImage;
use nalgebra::Vector3;
use ndarray::{s, Array4, ArrayView4};
use rayon::prelude::*;

use tre_core::geometry::{is_valid_point, Grid, PointMap, Vec3, INVALID_POINT};

/// Makes `t` a zeroed-or-reused `1 × channels × height × width` tensor: reallocates only when
/// the shape changes.
pub(crate) fn ensure_shape(t: &mut Array4<f32>, channels: usize, height: usize, width: usize) {
    if t.dim() != (1, channels, height, width) {
        *t = Array4::zeros((1, channels, height, width));
    }
}

/// Writes `value(x, y, c)` into every element of a `1 × C × H × W` tensor whose size is already
/// set, rows in parallel.
fn fill(t: &mut Array4<f32>, value: impl Fn(usize, usize, usize) -> f32 + Sync) {
    let (_, _, h, w) = t.dim();
    let data = t
        .as_slice_mut()
        .expect("tensors made by ensure_shape are contiguous; this is a bug");
    for (c, plane) in data.chunks_mut((h * w).max(1)).enumerate() {
        plane
            .par_chunks_mut(w.max(1))
            .enumerate()
            .for_each(|(y, row)| {
                for (x, v) in row.iter_mut().enumerate() {
                    *v = value(x, y, c);
                }
            });
    }
}

/// RGB as `1 × 3 × H × W` in [0, 1] (8-bit / 255).
pub(crate) fn rgb_tensor(rgb: &RgbImage, t: &mut Array4<f32>) {
    let (w, h) = (rgb.width() as usize, rgb.height() as usize);
    ensure_shape(t, 3, h, w);
    let raw = rgb.as_raw();
    fill(t, |x, y, c| f32::from(raw[(y * w + x) * 3 + c]) / 255.0);
}

/// A scalar map as `1 × 1 × H × W`.
pub(crate) fn scalar_tensor(map: &Grid<f64>, t: &mut Array4<f32>) {
    let (w, h) = map.size();
    ensure_shape(t, 1, h, w);
    fill(t, |x, y, _| map[(x, y)] as f32);
}

/// Points as `1 × 3 × H × W` metres (0 where invalid) and validity as `1 × 1 × H × W` (1/0).
pub(crate) fn points_tensors(
    points: &PointMap,
    points_t: &mut Array4<f32>,
    valid_t: &mut Array4<f32>,
) {
    let (w, h) = points.size();
    ensure_shape(points_t, 3, h, w);
    ensure_shape(valid_t, 1, h, w);
    let valid = valid_t
        .as_slice_mut()
        .expect("tensors made by ensure_shape are contiguous; this is a bug");
    let [p0, p1, p2] = plane_rows(points_t);
    p0.zip(p1)
        .zip(p2)
        .zip(valid.par_chunks_mut(w.max(1)))
        .enumerate()
        .for_each(|(y, (((r0, r1), r2), rv))| {
            for (x, p) in points.row(y).iter().enumerate() {
                let keep = is_valid_point(p);
                let v = if keep {
                    p.map(|c| c as f32)
                } else {
                    Vector3::zeros()
                };
                (r0[x], r1[x], r2[x]) = (v.x, v.y, v.z);
                rv[x] = f32::from(u8::from(keep));
            }
        });
}

/// Vectors (normals) as `1 × 3 × H × W`, 0 where a vector is not finite.
pub(crate) fn vectors_tensor(vectors: &Grid<Vec3>, t: &mut Array4<f32>) {
    let (w, h) = vectors.size();
    ensure_shape(t, 3, h, w);
    let [p0, p1, p2] = plane_rows(t);
    p0.zip(p1)
        .zip(p2)
        .enumerate()
        .for_each(|(y, ((r0, r1), r2))| {
            for (x, v) in vectors.row(y).iter().enumerate() {
                let keep = v.iter().all(|c| c.is_finite());
                let v = if keep {
                    v.map(|c| c as f32)
                } else {
                    Vector3::zeros()
                };
                (r0[x], r1[x], r2[x]) = (v.x, v.y, v.z);
            }
        });
}

/// The rows (in parallel) of the three planes of a `1 × 3 × H × W` tensor whose size is set.
fn plane_rows(t: &mut Array4<f32>) -> [rayon::slice::ChunksMut<'_, f32>; 3] {
    let (_, _, h, w) = t.dim();
    let data = t
        .as_slice_mut()
        .expect("tensors made by ensure_shape are contiguous; this is a bug");
    let (p0, rest) = data.split_at_mut(h * w);
    let (p1, p2) = rest.split_at_mut(h * w);
    [p0, p1, p2].map(|p| p.par_chunks_mut(w.max(1)))
}

/// Channel 0 of a `1 × 1 × H × W` depth tensor as metres into `out`, which takes the tensor's
/// size and keeps its buffer; non-positive or non-finite: 0.
pub(crate) fn depth_from_tensor_into(t: ArrayView4<'_, f32>, out: &mut Grid<f64>) {
    let (_, _, h, w) = t.dim();
    let plane = t.slice(s![0, 0, .., ..]);
    out.reset(w, h, 0.0);
    out.par_rows_mut().for_each(|(y, row)| {
        for (d, &v) in row.iter_mut().zip(plane.row(y)) {
            let v = f64::from(v);
            *d = if v > 0.0 && v.is_finite() { v } else { 0.0 };
        }
    });
}

/// Channels 0..3 of a `1 × 3 × H × W` tensor as vectors where `points` is valid, NaN elsewhere,
/// into `out`, which takes the size of `points` and keeps its buffer; `unit` normalises them (a
/// zero or non-finite vector becomes NaN).
pub(crate) fn vectors_from_tensor_into(
    t: ArrayView4<'_, f32>,
    points: &PointMap,
    unit: bool,
    out: &mut Grid<Vec3>,
) {
    let (w, h) = points.size();
    let planes = [0, 1, 2].map(|c| t.slice_move(s![0, c, .., ..]));
    out.reset(w, h, INVALID_POINT);
    out.par_rows_mut().for_each(|(y, row)| {
        let src = planes.each_ref().map(|p| p.row(y));
        for (x, (n, p)) in row.iter_mut().zip(points.row(y)).enumerate() {
            if !is_valid_point(p) {
                continue;
            }
            let v = Vec3::new(src[0][x].into(), src[1][x].into(), src[2][x].into());
            let v = if unit { v / v.norm() } else { v };
            if v.iter().all(|c| c.is_finite()) {
                *n = v;
            }
        }
    });
}
