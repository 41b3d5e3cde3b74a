//! Summed-area tables of a point map's moments: the count, Σp and Σppᵀ of the valid points of
//! any pixel rectangle in constant time, whatever its size (the terrain estimate's windows).

use super::{is_valid_point, Moments, PointMap, Vec3};

/// The ten moments of one prefix rectangle: count, Σx, Σy, Σz, Σxx, Σxy, Σxz, Σyy, Σyz, Σzz.
type Cell = [f64; 10];

/// Prefix sums of the moments of a point map's valid points, about a fixed origin (the mean of
/// the valid points, so that the sums of squares stay small and their differences exact to well
/// below a millimetre squared at 100 m).
#[derive(Debug, Clone, Default)]
pub struct SummedMoments {
    width: usize,
    height: usize,
    origin: Vec3,
    /// `(width + 1) × (height + 1)` cells; cell `(x, y)` holds the sums over `[0, x) × [0, y)`.
    table: Vec<Cell>,
}

impl SummedMoments {
    /// The table of `points` (invalid points left out), reusing this one's memory.
    pub fn build(&mut self, points: &PointMap) {
        let (w, h) = points.size();
        let (mut sum, mut n) = (Vec3::zeros(), 0.0f64);
        for p in points.as_slice().iter().filter(|p| is_valid_point(p)) {
            sum += p;
            n += 1.0;
        }
        self.origin = if n > 0.0 { sum / n } else { Vec3::zeros() };
        self.width = w;
        self.height = h;
        let stride = w + 1;
        self.table.clear();
        self.table.resize(stride * (h + 1), [0.0; 10]);
        for y in 0..h {
            let mut row: Cell = [0.0; 10];
            for (x, p) in points.row(y).iter().enumerate() {
                if is_valid_point(p) {
                    let d = p - self.origin;
                    let add = [
                        1.0,
                        d.x,
                        d.y,
                        d.z,
                        d.x * d.x,
                        d.x * d.y,
                        d.x * d.z,
                        d.y * d.y,
                        d.y * d.z,
                        d.z * d.z,
                    ];
                    for (r, a) in row.iter_mut().zip(add) {
                        *r += a;
                    }
                }
                let above = self.table[y * stride + x + 1];
                let cell = &mut self.table[(y + 1) * stride + x + 1];
                for ((c, r), a) in cell.iter_mut().zip(row).zip(above) {
                    *c = r + a;
                }
            }
        }
    }

    /// The origin the moments are taken about.
    pub fn origin(&self) -> Vec3 {
        self.origin
    }

    /// The moments (about [`origin`](Self::origin)) of the valid points in the pixel
    /// rectangle `[x0, x1) × [y0, y1)`, clipped to the map.
    pub fn rect(&self, (x0, y0): (isize, isize), (x1, y1): (isize, isize)) -> Moments {
        let clip = |v: isize, hi: usize| v.clamp(0, hi as isize) as usize;
        let (x0, x1) = (clip(x0, self.width), clip(x1, self.width));
        let (y0, y1) = (clip(y0, self.height), clip(y1, self.height));
        if x1 <= x0 || y1 <= y0 {
            return Moments::default();
        }
        let stride = self.width + 1;
        let at = |x: usize, y: usize| &self.table[y * stride + x];
        let (a, b, c, d) = (at(x1, y1), at(x0, y1), at(x1, y0), at(x0, y0));
        let s: Cell = std::array::from_fn(|i| a[i] - b[i] - c[i] + d[i]);
        Moments {
            // Counts are whole numbers, summed exactly.
            count: (s[0] + 0.5) as u32,
            sum: Vec3::new(s[1], s[2], s[3]),
            sum_sq: [s[4], s[5], s[6], s[7], s[8], s[9]],
        }
    }

    /// The moments of the square window of half-width `half` around pixel `(x, y)`.
    pub fn window(&self, (x, y): (usize, usize), half: usize) -> Moments {
        let (x, y, r) = (x as isize, y as isize, half as isize);
        self.rect((x - r, y - r), (x + r + 1, y + r + 1))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::{Grid, INVALID_POINT};

    #[test]
    fn rectangles_sum_what_a_loop_sums() {
        let points = Grid::from_fn(13, 9, |x, y| {
            if (x * 7 + y * 3) % 5 == 0 {
                INVALID_POINT
            } else {
                Vec3::new(
                    x as f64 * 0.1,
                    y as f64 * 0.2 - 0.3,
                    2.0 + ((x * y) % 7) as f64 * 0.01,
                )
            }
        });
        let mut t = SummedMoments::default();
        t.build(&points);
        let o = t.origin();
        for (x0, y0, x1, y1) in [(0, 0, 13, 9), (2, 1, 7, 8), (-3, -2, 4, 3), (5, 5, 5, 9)] {
            let got = t.rect((x0, y0), (x1, y1));
            let mut want = Moments::default();
            for y in y0.max(0)..y1.min(9) {
                for x in x0.max(0)..x1.min(13) {
                    let p = points[(x as usize, y as usize)];
                    if is_valid_point(&p) {
                        want.add(&(p - o));
                    }
                }
            }
            assert_eq!(got.count, want.count);
            assert!((got.sum - want.sum).norm() < 1e-12);
            for (g, w) in got.sum_sq.iter().zip(want.sum_sq) {
                assert!((g - w).abs() < 1e-12);
            }
        }
    }
}
