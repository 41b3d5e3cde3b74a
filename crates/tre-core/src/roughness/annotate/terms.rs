//! Steps 4 to 6: the edge term, the surface term (Eq. 1) and the edge transient.

use super::*;

/// Step 4's edge term: W where W ≥ ε, 2W where 0.5ε < W < ε, else 0.
///
/// ```
/// use tre_core::roughness::annotate::edge_term;
/// assert_eq!(edge_term(0.02, 0.015), 0.02);
/// assert_eq!(edge_term(0.01, 0.015), 0.02);
/// assert_eq!(edge_term(0.005, 0.015), 0.0);
/// ```
pub fn edge_term(w_m: f64, epsilon_m: f64) -> f64 {
    if w_m >= epsilon_m {
        w_m
    } else if w_m > 0.5 * epsilon_m {
        2.0 * w_m
    } else {
        0.0
    }
}

/// Step 5, Eq. 1 of the paper at every pixel into `out` (same size): `|n·(p − c)|`
/// ([`Plane::distance`]), NaN where the point, the normal or the centroid is missing. Rows in
/// parallel. The one implementation of Eq. 1 over a map: the annotator, the `geometric` mode
/// and the learned modes (with the centroid net's centroids) all call it.
///
/// ```
/// use tre_core::geometry::{Grid, Vec3};
/// use tre_core::roughness::annotate::surface_term_into;
/// let points = Grid::new(2, 1, Vec3::new(0.0, 0.0, 1.0));
/// let normals = Grid::new(2, 1, Vec3::new(0.0, 0.0, -1.0));
/// let centroids = Grid::new(2, 1, Vec3::new(0.5, 0.0, 1.02));
/// let mut r = Grid::new(2, 1, 0.0);
/// surface_term_into(&points, &normals, &centroids, &mut r);
/// assert!((r[(1, 0)] - 0.02).abs() < 1e-12);
/// ```
pub fn surface_term_into(
    points: &PointMap,
    normals: &Grid<Vec3>,
    centroids: &PointMap,
    out: &mut Grid<f64>,
) {
    out.par_rows_mut().for_each(|(y, row)| {
        for (x, r) in row.iter_mut().enumerate() {
            let p = points[(x, y)];
            *r = if is_valid_point(&p) {
                let plane = Plane {
                    centroid: centroids[(x, y)],
                    normal: normals[(x, y)],
                };
                plane.distance(&p)
            } else {
                f64::NAN
            };
        }
    });
}

/// Step 6: `ẽ_i = max_j e_j·exp(−d_ij²/2σ²)` over pixels j within 3σ (pixel distance), at valid
/// i, from the edge terms `edge` (0 where none).
pub fn edge_transient(edge: &Grid<f64>, points: &PointMap, sigma_px: f64) -> Grid<f64> {
    let mut rows = EdgeRows::default();
    rows.collect_terms(edge);
    let mut out = Grid::default();
    rows.transient_into(points, sigma_px, &mut out);
    out
}

/// The pixels with an edge term, row by row: the transient visits only these, as a boundary
/// covers a small part of a frame.
#[derive(Debug, Clone, Default)]
pub(super) struct EdgeRows {
    /// `(x, e_x)` of each row's pixels with `e > 0`, rows one after another.
    terms: Vec<(u32, f64)>,
    /// Where each row's terms start in `terms` (height + 1 entries).
    row_start: Vec<usize>,
}

impl EdgeRows {
    /// The edge terms (step 4) of the edge weights `w_m`.
    pub(super) fn collect(&mut self, w_m: &Grid<f64>, epsilon_m: f64) {
        self.gather(w_m, |w| edge_term(w, epsilon_m));
    }

    /// Edge terms given as a map.
    pub(super) fn collect_terms(&mut self, e: &Grid<f64>) {
        self.gather(e, |e| e);
    }

    pub(super) fn gather(&mut self, grid: &Grid<f64>, term: impl Fn(f64) -> f64) {
        let h = grid.height();
        self.terms.clear();
        self.row_start.clear();
        for y in 0..h {
            self.row_start.push(self.terms.len());
            for (x, &v) in grid.row(y).iter().enumerate() {
                let e = term(v);
                if e > 0.0 {
                    self.terms.push((x as u32, e));
                }
            }
        }
        self.row_start.push(self.terms.len());
    }

    /// Step 6 into `out` (the points' size): each output row takes the maximum over the terms
    /// of the rows within 3σ, weighted by `exp(−d²/2σ²)`; 0 at invalid pixels and where no term
    /// reaches.
    pub(super) fn transient_into(&self, points: &PointMap, sigma_px: f64, out: &mut Grid<f64>) {
        let (w, h) = points.size();
        let kernel = TransientKernel::new(sigma_px);
        let reach = kernel.reach;
        out.reset(w, h, 0.0);
        out.par_rows_mut().for_each(|(y, row)| {
            let (y0, y1) = (
                y.saturating_sub(reach),
                (y + reach).min(h.saturating_sub(1)),
            );
            for yy in y0..=y1 {
                let (half, weights) = kernel.row(yy.abs_diff(y));
                for &(xx, e) in &self.terms[self.row_start[yy]..self.row_start[yy + 1]] {
                    let xx = xx as usize;
                    // Columns xx − half ..= xx + half, clipped to the row; weights[reach + dx].
                    let (x0, x1) = (xx.saturating_sub(half), (xx + half + 1).min(w));
                    let wts = &weights[x0 + reach - xx..x1 + reach - xx];
                    for (o, &wt) in row[x0..x1].iter_mut().zip(wts) {
                        *o = o.max(e * wt);
                    }
                }
            }
            // Pixels without a point have no roughness, so no transient either.
            for (o, p) in row.iter_mut().zip(points.row(y)) {
                if !is_valid_point(p) {
                    *o = 0.0;
                }
            }
        });
    }
}

/// The weights of the edge transient, `exp(−(dx² + dy²)/2σ²)` for pixel offsets within 3σ,
/// row by row, with the definition's expression (bit for bit).
pub(super) struct TransientKernel {
    /// `⌊3σ⌋`: the largest offset along an axis.
    reach: usize,
    /// Per |dy|: the largest |dx| within 3σ, and the weights of dx = −reach ..= reach (0
    /// outside the disc).
    rows: Vec<(usize, Vec<f64>)>,
}

impl TransientKernel {
    pub(super) fn new(sigma_px: f64) -> Self {
        let reach = (3.0 * sigma_px).floor().max(0.0) as usize;
        let limit = 9.0 * sigma_px * sigma_px;
        let rows = (0..=reach)
            .map(|dy| {
                let mut half = 0;
                let weights = (0..=2 * reach)
                    .map(|i| {
                        let dx = i.abs_diff(reach);
                        let d2 = (dx * dx + dy * dy) as f64;
                        if d2 > limit {
                            return 0.0;
                        }
                        half = half.max(dx);
                        (-d2 / (2.0 * sigma_px * sigma_px)).exp()
                    })
                    .collect();
                (half, weights)
            })
            .collect();
        Self { reach, rows }
    }

    /// The half-width and weights of row offset `dy` (≤ reach).
    pub(super) fn row(&self, dy: usize) -> (usize, &[f64]) {
        let (half, weights) = &self.rows[dy];
        (*half, weights)
    }
}
