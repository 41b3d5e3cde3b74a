//! What the fused ground says about a cell: roughness and slope from the plane of its
//! neighbourhood's heights, and the step down to its lowest neighbour (docs/map.md).

use crate::geometry::NEIGHBOURS_8;

/// The fused ground of a window, in the layers' layout: height and variance per cell (NaN:
/// not seen).
pub(crate) struct Ground {
    pub(crate) side: usize,
    pub(crate) cell_m: f64,
    pub(crate) height: Vec<f64>,
    pub(crate) var: Vec<f64>,
}

/// Roughness and slope of one cell's neighbourhood.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct Surface {
    /// Scatter of the heights about their plane less what their variances explain, metres.
    pub(crate) roughness_m: f64,
    /// The plane's slope, radians.
    pub(crate) slope_rad: f64,
}

impl Ground {
    fn at(&self, c: isize, r: isize) -> Option<(f64, f64)> {
        let s = self.side as isize;
        if c < 0 || r < 0 || c >= s || r >= s {
            return None;
        }
        let i = r as usize * self.side + c as usize;
        self.height[i]
            .is_finite()
            .then(|| (self.height[i], self.var[i]))
    }

    /// The weighted least-squares plane `h = a + b·dx + c·dy` of the seen cells within `radius`
    /// cells of `(col, row)` whose height is within `max_step_m` of the cell's, plus what a
    /// slope of `max_slope_rad` climbs over the distance (a cell beyond is another surface:
    /// the step says so), weights `1 / variance`. Roughness: the weighted
    /// mean squared residual less `(n − 3) / Σw` (what white height noise of those variances
    /// leaves after a plane fit), its root, 0 when noise explains it all. `None` for fewer
    /// than 6 cells or cells on one line.
    pub(crate) fn surface(
        &self,
        (col, row): (usize, usize),
        radius: usize,
        (max_step_m, max_slope_rad): (f64, f64),
    ) -> Option<Surface> {
        let climb = max_slope_rad.tan();
        let (c0, r0) = (col as isize, row as isize);
        let (h0, _) = self.at(c0, r0)?;
        let rad = radius as isize;
        let mut cells = Vec::with_capacity((2 * radius + 1).pow(2));
        for dr in -rad..=rad {
            for dc in -rad..=rad {
                if let Some((h, v)) = self.at(c0 + dc, r0 + dr) {
                    let (x, y) = (dc as f64 * self.cell_m, -(dr as f64) * self.cell_m);
                    if (h - h0).abs() <= max_step_m + climb * x.hypot(y) {
                        cells.push((x, y, h - h0, 1.0 / v.max(1e-10)));
                    }
                }
            }
        }
        if cells.len() < 6 {
            return None;
        }
        let plane = fit_plane(&cells)?;
        let (mut sw, mut sr) = (0.0, 0.0);
        for &(x, y, h, w) in &cells {
            let r = h - (plane[0] + plane[1] * x + plane[2] * y);
            sw += w;
            sr += w * r * r;
        }
        let noise = (cells.len() as f64 - 3.0) / sw;
        Some(Surface {
            roughness_m: (sr / sw - noise).max(0.0).sqrt(),
            slope_rad: plane[1].hypot(plane[2]).atan(),
        })
    }

    /// How far the cell stands above its lowest seen 8-neighbour, less two σ of the difference
    /// (0 when noise explains it; NaN without a seen neighbour). The step sits on the upper
    /// side of an edge (the obstacle, or the brink of a drop); the ground below it stays
    /// what it is.
    pub(crate) fn step(&self, (col, row): (usize, usize)) -> f64 {
        let (c0, r0) = (col as isize, row as isize);
        let Some((h0, v0)) = self.at(c0, r0) else {
            return f64::NAN;
        };
        NEIGHBOURS_8
            .iter()
            .filter_map(|&(dc, dr)| self.at(c0 + dc as isize, r0 + dr as isize))
            .map(|(h, v)| (h0 - h - 2.0 * (v0 + v).sqrt()).max(0.0))
            .fold(f64::NAN, f64::max)
    }
}

/// The weighted least-squares plane `[a, b, c]` of `(x, y, h, w)` points, `None` when they lie
/// on a line.
fn fit_plane(cells: &[(f64, f64, f64, f64)]) -> Option<[f64; 3]> {
    let mut m = nalgebra::Matrix3::<f64>::zeros();
    let mut v = nalgebra::Vector3::<f64>::zeros();
    for &(x, y, h, w) in cells {
        let a = nalgebra::Vector3::new(1.0, x, y);
        m += w * a * a.transpose();
        v += w * h * a;
    }
    let scale = m[(0, 0)];
    if !(scale > 0.0) || m.determinant().abs() <= 1e-12 * scale.powi(3) {
        return None;
    }
    let p = m.lu().solve(&v)?;
    Some([p.x, p.y, p.z])
}
