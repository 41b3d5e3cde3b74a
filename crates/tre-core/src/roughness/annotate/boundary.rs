//! Steps 3 and 4: the boundary mask and the edge weights.

use super::*;

/// The valid 8-neighbours of `(x, y)`, as flat indices.
pub(super) fn neighbours8(w: usize, h: usize, x: usize, y: usize) -> impl Iterator<Item = usize> {
    (-1isize..=1)
        .flat_map(move |dy| (-1isize..=1).map(move |dx| (dx, dy)))
        .filter_map(move |(dx, dy)| {
            let (nx, ny) = (x as isize + dx, y as isize + dy);
            let inside =
                (dx, dy) != (0, 0) && nx >= 0 && ny >= 0 && (nx as usize) < w && (ny as usize) < h;
            inside.then(|| ny as usize * w + nx as usize)
        })
}

/// Step 3: valid pixels with a valid 8-neighbour in another segment.
pub fn boundary_mask(points: &PointMap, segments: &Grid<u32>) -> Grid<bool> {
    let mut out = Grid::default();
    boundary_mask_into(points, segments, &mut out);
    out
}

/// [`boundary_mask`] into `out` (resized to the points' size).
pub(super) fn boundary_mask_into(points: &PointMap, segments: &Grid<u32>, out: &mut Grid<bool>) {
    let (w, h) = points.size();
    let s = segments.as_slice();
    out.reset(w, h, false);
    out.par_rows_mut().for_each(|(y, row)| {
        let rows = [y.checked_sub(1), Some(y), (y + 1 < h).then_some(y + 1)];
        let rows: Vec<&[u32]> = rows
            .iter()
            .flatten()
            .map(|&r| &s[r * w..(r + 1) * w])
            .collect();
        for (x, b) in row.iter_mut().enumerate() {
            let v = s[y * w + x];
            let (x0, x1) = (x.saturating_sub(1), (x + 1).min(w - 1));
            // The pixel itself is in its own segment, so it never counts.
            *b = v != 0
                && rows
                    .iter()
                    .any(|r| r[x0..=x1].iter().any(|&t| t != 0 && t != v));
        }
    });
}

/// Step 4: on boundary pixels, the largest distance to a valid 8-neighbour; 0 elsewhere.
pub fn edge_weights(points: &PointMap, boundary: &Grid<bool>) -> Grid<f64> {
    let mut out = Grid::default();
    edge_weights_into(points, boundary, &mut out);
    out
}

/// [`edge_weights`] into `out` (resized to the points' size).
pub(super) fn edge_weights_into(points: &PointMap, boundary: &Grid<bool>, out: &mut Grid<f64>) {
    let (w, h) = points.size();
    let p = points.as_slice();
    out.reset(w, h, 0.0);
    out.par_rows_mut().for_each(|(y, row)| {
        for (x, o) in row.iter_mut().enumerate() {
            let i = y * w + x;
            if boundary.as_slice()[i] {
                *o = neighbours8(w, h, x, y)
                    .filter(|&j| is_valid_point(&p[j]))
                    .map(|j| (p[j] - p[i]).norm())
                    .fold(0.0, f64::max);
            }
        }
    });
}
