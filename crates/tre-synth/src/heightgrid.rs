//! A terrain sampled on a regular grid and rendered as bilinear patches: exact ray intersection
//! (a quadratic per cell), exact normals of the patch, and a block-maximum grid so that rays skip
//! empty space. The patches *are* the rendered geometry, so depth and normals agree exactly.

use rayon::prelude::*;

use super::terrain::Terrain;
use tre_core::geometry::Vec3;

/// Cells per side of a skipping block.
const BLOCK: usize = 16;

/// Heights on a regular grid of vertices (metres, gravity frame, z up).
#[derive(Debug, Clone)]
pub struct HeightGrid {
    x0: f64,
    y0: f64,
    cell_m: f64,
    nx: usize,
    ny: usize,
    heights: Vec<f32>,
    /// Per vertex, 1 + the index of the terrain object whose surface it is (0: a region's);
    /// empty when the terrain has no objects.
    owners: Vec<u16>,
    block_max: Vec<f32>,
    bnx: usize,
    max_h: f64,
}

impl HeightGrid {
    /// Samples `terrain` over `[x0, x1] × [y0, y1]` every `cell_m` metres (row-parallel).
    pub fn sample(
        terrain: &Terrain,
        (x0, y0): (f64, f64),
        (x1, y1): (f64, f64),
        cell_m: f64,
    ) -> Self {
        let nx = ((x1 - x0) / cell_m).ceil().max(1.0) as usize;
        let ny = ((y1 - y0) / cell_m).ceil().max(1.0) as usize;
        let mut heights = vec![0f32; (nx + 1) * (ny + 1)];
        let mut owners = Vec::new();
        if terrain.objects.is_empty() {
            heights
                .par_chunks_mut(nx + 1)
                .enumerate()
                .for_each(|(j, row)| {
                    for (i, h) in row.iter_mut().enumerate() {
                        *h = terrain.height(x0 + i as f64 * cell_m, y0 + j as f64 * cell_m) as f32;
                    }
                });
        } else {
            owners = vec![0u16; heights.len()];
            heights
                .par_chunks_mut(nx + 1)
                .zip(owners.par_chunks_mut(nx + 1))
                .enumerate()
                .for_each(|(j, (row, own))| {
                    for (i, (h, o)) in row.iter_mut().zip(own.iter_mut()).enumerate() {
                        let (x, y) = (x0 + i as f64 * cell_m, y0 + j as f64 * cell_m);
                        let (z, k) = terrain.height_owner(x, y, cell_m);
                        *h = z as f32;
                        *o = k.map_or(0, |k| u16::try_from(k + 1).unwrap_or(u16::MAX));
                    }
                });
        }
        let mut grid = Self::from_heights((x0, y0), cell_m, (nx, ny), heights);
        grid.owners = owners;
        grid
    }

    fn from_heights(
        (x0, y0): (f64, f64),
        cell_m: f64,
        (nx, ny): (usize, usize),
        heights: Vec<f32>,
    ) -> Self {
        let (bnx, bny) = (nx.div_ceil(BLOCK), ny.div_ceil(BLOCK));
        let mut block_max = vec![f32::NEG_INFINITY; bnx * bny];
        for j in 0..=ny {
            for i in 0..=nx {
                let h = heights[j * (nx + 1) + i];
                // A vertex bounds every block whose cells touch it.
                for bj in (j.saturating_sub(1) / BLOCK)..=(j / BLOCK).min(bny - 1) {
                    for bi in (i.saturating_sub(1) / BLOCK)..=(i / BLOCK).min(bnx - 1) {
                        let m = &mut block_max[bj * bnx + bi];
                        *m = m.max(h);
                    }
                }
            }
        }
        let max_h = heights.iter().fold(f32::NEG_INFINITY, |a, &b| a.max(b)) as f64;
        Self {
            x0,
            y0,
            cell_m,
            nx,
            ny,
            heights,
            owners: Vec::new(),
            block_max,
            bnx,
            max_h,
        }
    }

    fn h(&self, i: usize, j: usize) -> f64 {
        f64::from(self.heights[j * (self.nx + 1) + i])
    }

    /// The patch of cell `(i, j)`: `H(u, v) = a + b·u + c·v + e·u·v` over u, v ∈ [0, 1].
    fn patch(&self, i: usize, j: usize) -> [f64; 4] {
        let (h00, h10, h01, h11) = (
            self.h(i, j),
            self.h(i + 1, j),
            self.h(i, j + 1),
            self.h(i + 1, j + 1),
        );
        [h00, h10 - h00, h01 - h00, h00 - h10 - h01 + h11]
    }

    /// The cell holding ground point `(x, y)` and the point's patch coordinates, if inside.
    fn locate(&self, x: f64, y: f64) -> Option<(usize, usize, f64, f64)> {
        let (gx, gy) = ((x - self.x0) / self.cell_m, (y - self.y0) / self.cell_m);
        if !(gx >= 0.0 && gy >= 0.0 && gx <= self.nx as f64 && gy <= self.ny as f64) {
            return None;
        }
        let (i, j) = (
            (gx as usize).min(self.nx - 1),
            (gy as usize).min(self.ny - 1),
        );
        Some((i, j, gx - i as f64, gy - j as f64))
    }

    /// Height of the rendered surface at `(x, y)`, if on the grid.
    pub fn height(&self, x: f64, y: f64) -> Option<f64> {
        let (i, j, u, v) = self.locate(x, y)?;
        let [a, b, c, e] = self.patch(i, j);
        Some(a + b * u + c * v + e * u * v)
    }

    /// The terrain object whose surface the rendered point `(x, y)` lies on, by its cell: of the
    /// objects owning the cell's four vertices, the last drawn. So the face of a cell that
    /// joins a floor to a box top (a step in the height field) belongs to the box. `None`: a
    /// region's surface (also off the grid, or for a terrain without objects).
    #[inline]
    pub fn owner(&self, x: f64, y: f64) -> Option<usize> {
        if self.owners.is_empty() {
            return None;
        }
        let (i, j, _, _) = self.locate(x, y)?;
        let at = |i: usize, j: usize| self.owners[j * (self.nx + 1) + i];
        let k = at(i, j)
            .max(at(i + 1, j))
            .max(at(i, j + 1))
            .max(at(i + 1, j + 1));
        (k > 0).then(|| usize::from(k - 1))
    }

    /// Unit upward normal of the rendered surface at `(x, y)`, if on the grid.
    pub fn normal(&self, x: f64, y: f64) -> Option<Vec3> {
        let (i, j, u, v) = self.locate(x, y)?;
        let [_, b, c, e] = self.patch(i, j);
        Some(Vec3::new(-(b + e * v) / self.cell_m, -(c + e * u) / self.cell_m, 1.0).normalize())
    }

    /// Distance along the unit ray `o + t·d` to its first intersection with the surface:
    /// blocks whose highest vertex the ray passes above are skipped whole.
    pub fn intersect(&self, o: &Vec3, d: &Vec3, t_max: f64) -> Option<f64> {
        let (t, t_end) = self.clip(o, d, t_max)?;
        let blocks = (self.bnx, self.ny.div_ceil(BLOCK));
        walk(
            o,
            d,
            (t, t_end),
            (self.x0, self.y0),
            self.cell_m * BLOCK as f64,
            blocks,
            |bi, bj, t0, t1| {
                let z_low = (o.z + t0 * d.z).min(o.z + t1 * d.z);
                if z_low > f64::from(self.block_max[bj * self.bnx + bi]) {
                    return None;
                }
                walk(
                    o,
                    d,
                    (t0, t1),
                    (self.x0, self.y0),
                    self.cell_m,
                    (self.nx, self.ny),
                    |i, j, c0, c1| self.intersect_cell(o, d, i, j, c0, c1),
                )
            },
        )
    }

    /// Clips the ray to the grid's footprint and to heights at or below the highest vertex.
    fn clip(&self, o: &Vec3, d: &Vec3, t_max: f64) -> Option<(f64, f64)> {
        let (x1, y1) = (
            self.x0 + self.nx as f64 * self.cell_m,
            self.y0 + self.ny as f64 * self.cell_m,
        );
        let (mut t0, mut t1) = (0.0f64, t_max);
        for (o, d, lo, hi) in [(o.x, d.x, self.x0, x1), (o.y, d.y, self.y0, y1)] {
            if d.abs() < 1e-15 {
                if o < lo || o > hi {
                    return None;
                }
                continue;
            }
            let (a, b) = ((lo - o) / d, (hi - o) / d);
            t0 = t0.max(a.min(b));
            t1 = t1.min(a.max(b));
        }
        if o.z > self.max_h {
            if d.z >= 0.0 {
                return None;
            }
            t0 = t0.max((o.z - self.max_h) / -d.z);
        } else if d.z > 0.0 {
            t1 = t1.min((self.max_h - o.z) / d.z);
        }
        (t0 < t1).then_some((t0, t1))
    }

    /// Exact intersection with the bilinear patch of cell `(i, j)` for `t ∈ [t0, t1]`.
    fn intersect_cell(
        &self,
        o: &Vec3,
        d: &Vec3,
        i: usize,
        j: usize,
        t0: f64,
        t1: f64,
    ) -> Option<f64> {
        let cell_max = self
            .h(i, j)
            .max(self.h(i + 1, j))
            .max(self.h(i, j + 1))
            .max(self.h(i + 1, j + 1));
        if (o.z + t0 * d.z).min(o.z + t1 * d.z) > cell_max {
            return None;
        }
        let [a, b, c, e] = self.patch(i, j);
        let u0 = (o.x + t0 * d.x - self.x0) / self.cell_m - i as f64;
        let v0 = (o.y + t0 * d.y - self.y0) / self.cell_m - j as f64;
        let (du, dv) = (d.x / self.cell_m, d.y / self.cell_m);
        // g(s) = ray height − surface height at t0 + s: a quadratic in s.
        let qa = -e * du * dv;
        let qb = d.z - (b * du + c * dv + e * (u0 * dv + v0 * du));
        let qc = (o.z + t0 * d.z) - (a + b * u0 + c * v0 + e * u0 * v0);
        let s = first_root(qa, qb, qc, t1 - t0)?;
        Some(t0 + s)
    }
}

/// The smallest s in [0, len] where `a·s² + b·s + c` reaches 0 from above (c > 0), if any.
fn first_root(a: f64, b: f64, c: f64, len: f64) -> Option<f64> {
    if c <= 0.0 {
        return Some(0.0);
    }
    let slack = 1e-9 * (1.0 + len);
    let ok = |s: f64| (s >= 0.0 && s <= len + slack).then_some(s.min(len));
    if a.abs() < 1e-12 * (b.abs() + c.abs()) {
        return if b < 0.0 { ok(-c / b) } else { None };
    }
    let disc = b * b - 4.0 * a * c;
    if disc < 0.0 {
        return None;
    }
    let q = -0.5 * (b + b.signum() * disc.sqrt());
    let (r1, r2) = (q / a, if q != 0.0 { c / q } else { f64::INFINITY });
    let (lo, hi) = (r1.min(r2), r1.max(r2));
    ok(lo).or_else(|| ok(hi))
}

/// Walks the cells (of `size` metres from `origin`, `n` per side) that the ray crosses over
/// `[t, t_end]`, calling `visit(i, j, t_in, t_out)` on each until one returns a hit.
fn walk(
    o: &Vec3,
    d: &Vec3,
    (mut t, t_end): (f64, f64),
    (x0, y0): (f64, f64),
    size: f64,
    (nx, ny): (usize, usize),
    mut visit: impl FnMut(usize, usize, f64, f64) -> Option<f64>,
) -> Option<f64> {
    while t < t_end {
        let (i, j, t_out) = dda_step(o, d, t, x0, y0, size)?;
        if i >= nx || j >= ny {
            return None;
        }
        let t_out = t_out.min(t_end);
        if let Some(hit) = visit(i, j, t, t_out) {
            return Some(hit);
        }
        t = t_out;
    }
    None
}

/// The grid cell (cells of `size` metres from `(x0, y0)`) that the ray occupies just after `t`,
/// and the parameter where it leaves that cell.
fn dda_step(
    o: &Vec3,
    d: &Vec3,
    t: f64,
    x0: f64,
    y0: f64,
    size: f64,
) -> Option<(usize, usize, f64)> {
    // Probe a hair past t so that a ray on a cell boundary lands in the next cell.
    let probe = t + 1e-9;
    let (gx, gy) = (
        (o.x + probe * d.x - x0) / size,
        (o.y + probe * d.y - y0) / size,
    );
    if !(gx >= 0.0 && gy >= 0.0) {
        return None;
    }
    let (i, j) = (gx.floor(), gy.floor());
    let exit = |o: f64, d: f64, base: f64, k: f64| {
        if d > 0.0 {
            (base + (k + 1.0) * size - o) / d
        } else if d < 0.0 {
            (base + k * size - o) / d
        } else {
            f64::INFINITY
        }
    };
    let t_out = exit(o.x, d.x, x0, i).min(exit(o.y, d.y, y0, j)).max(probe);
    Some((i as usize, j as usize, t_out))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::surface::Category;
    use crate::terrain::Terrain;

    #[test]
    fn rays_hit_the_bilinear_surface_exactly() {
        let terrain = Terrain::uniform(Category::Sand, 4);
        let g = HeightGrid::sample(&terrain, (-3.0, -1.0), (3.0, 4.0), 0.004);
        let o = Vec3::new(0.0, 0.0, 1.0);
        let mut hits = 0;
        for k in 0..400 {
            let (a, e) = (-0.8 + 0.004 * k as f64, -0.3 - 0.002 * k as f64);
            let d = Vec3::new(a.sin() * e.cos(), a.cos() * e.cos(), e.sin()).normalize();
            if let Some(t) = g.intersect(&o, &d, 50.0) {
                let p = o + d * t;
                assert!((p.z - g.height(p.x, p.y).unwrap()).abs() < 1e-7, "ray {k}");
                hits += 1;
            }
        }
        assert!(hits > 300);
    }

    #[test]
    fn first_root_finds_the_entry() {
        // (s − 1)(s − 3) = s² − 4s + 3: first crossing at 1.
        assert_eq!(first_root(1.0, -4.0, 3.0, 5.0), Some(1.0));
        assert_eq!(first_root(1.0, -4.0, 3.0, 0.5), None);
        assert_eq!(first_root(0.0, -2.0, 1.0, 1.0), Some(0.5));
    }
}
