//! Step 2: segments, 4-connected components of neighbours that join, found by bands of rows in parallel.

use super::*;

/// Step 2: 4-connected components of valid pixels with the same label, normals within the
/// segment angle and point-to-tangent-plane distance under ε (both ways).
pub fn segment(
    points: &PointMap,
    normals: &Grid<Vec3>,
    labels: Option<&Grid<u32>>,
    cfg: &AnnotateConfig,
) -> Grid<u32> {
    let mut out = Grid::default();
    segment_into(
        points,
        normals,
        labels,
        cfg,
        &mut DisjointSets::default(),
        &mut out,
    );
    out
}

/// Rows per band of the parallel union-find.
pub(super) const BAND_ROWS: usize = 32;

/// [`segment`] into `out`, with `forest` as scratch (both reused across frames). Bands of rows
/// join their own pixels in parallel; the joins across band borders follow; the partition is
/// the same as one pass gives, since components do not depend on the order of unions.
pub(super) fn segment_into(
    points: &PointMap,
    normals: &Grid<Vec3>,
    labels: Option<&Grid<u32>>,
    cfg: &AnnotateConfig,
    forest: &mut DisjointSets,
    out: &mut Grid<u32>,
) {
    let (w, h) = points.size();
    let joiner = Joiner::new(points, normals, labels, cfg);
    forest.reset(w * h);
    let band = BAND_ROWS * w.max(1);
    forest
        .parent
        .par_chunks_mut(band)
        .zip(forest.size.par_chunks_mut(band))
        .enumerate()
        .for_each(|(b, (parent, size))| {
            let mut sets = SetsView {
                parent,
                size,
                offset: b * band,
            };
            let rows = sets.parent.len() / w.max(1);
            for ly in 0..rows {
                for x in 0..w {
                    let i = sets.offset + ly * w + x;
                    if x + 1 < w && joiner.joins(i, i + 1) {
                        sets.union(i, i + 1);
                    }
                    if ly + 1 < rows && joiner.joins(i, i + w) {
                        sets.union(i, i + w);
                    }
                }
            }
        });
    for y in (BAND_ROWS..h).step_by(BAND_ROWS) {
        for x in 0..w {
            let i = (y - 1) * w + x;
            if joiner.joins(i, i + w) {
                forest.union(i, i + w);
            }
        }
    }
    forest.compact_ids(points, out);
}

/// Whether two neighbouring pixels belong to one segment (spec step 2): both valid, the same
/// label, normals within the segment angle, each point within ε of the other's tangent plane.
pub(super) struct Joiner<'a> {
    points: &'a [Vec3],
    normals: &'a [Vec3],
    labels: Option<&'a [u32]>,
    cos_max: f64,
    epsilon_m: f64,
}

impl<'a> Joiner<'a> {
    pub(super) fn new(
        points: &'a PointMap,
        normals: &'a Grid<Vec3>,
        labels: Option<&'a Grid<u32>>,
        cfg: &AnnotateConfig,
    ) -> Self {
        Self {
            points: points.as_slice(),
            normals: normals.as_slice(),
            labels: labels.map(Grid::as_slice),
            cos_max: cfg.segment_angle_deg.to_radians().cos(),
            epsilon_m: cfg.epsilon_m,
        }
    }

    pub(super) fn joins(&self, i: usize, j: usize) -> bool {
        let (pi, pj) = (self.points[i], self.points[j]);
        let (ni, nj) = (self.normals[i], self.normals[j]);
        let label = |k: usize| self.labels.map_or(1, |l| l[k]);
        is_valid_point(&pi)
            && is_valid_point(&pj)
            && label(i) == label(j)
            && ni.dot(&nj) > self.cos_max
            && ni.dot(&(pj - pi)).abs() < self.epsilon_m
            && nj.dot(&(pi - pj)).abs() < self.epsilon_m
    }
}

/// Union-find with path halving and union by size; `id` numbers the roots compactly.
#[derive(Debug, Clone, Default)]
pub(super) struct DisjointSets {
    parent: Vec<u32>,
    size: Vec<u32>,
    id: Vec<u32>,
}

/// Union-find over a contiguous range of the pixels (`offset ..`), on slices of a
/// [`DisjointSets`]' arrays: parents hold whole-frame indices.
pub(super) struct SetsView<'a> {
    parent: &'a mut [u32],
    size: &'a mut [u32],
    offset: usize,
}

impl SetsView<'_> {
    pub(super) fn find(&mut self, i: usize) -> usize {
        let off = self.offset;
        let mut i = i as u32;
        while self.parent[i as usize - off] != i {
            let up = self.parent[self.parent[i as usize - off] as usize - off];
            self.parent[i as usize - off] = up;
            i = up;
        }
        i as usize
    }

    pub(super) fn union(&mut self, a: usize, b: usize) {
        let (mut ra, mut rb) = (self.find(a), self.find(b));
        if ra == rb {
            return;
        }
        let off = self.offset;
        if self.size[ra - off] < self.size[rb - off] {
            std::mem::swap(&mut ra, &mut rb);
        }
        self.parent[rb - off] = ra as u32;
        self.size[ra - off] += self.size[rb - off];
    }
}

impl DisjointSets {
    /// `n` singletons, keeping the buffers.
    pub(super) fn reset(&mut self, n: usize) {
        self.parent.clear();
        self.parent.extend(0..n as u32);
        self.size.clear();
        self.size.resize(n, 1);
    }

    pub(super) fn view(&mut self) -> SetsView<'_> {
        SetsView {
            parent: &mut self.parent,
            size: &mut self.size,
            offset: 0,
        }
    }

    pub(super) fn find(&mut self, i: usize) -> usize {
        self.view().find(i)
    }

    pub(super) fn union(&mut self, a: usize, b: usize) {
        self.view().union(a, b);
    }

    /// Numbers the components 1, 2, … in raster order of their first pixel into `out`;
    /// invalid pixels get 0.
    pub(super) fn compact_ids(&mut self, points: &PointMap, out: &mut Grid<u32>) {
        let (w, h) = points.size();
        let mut id = std::mem::take(&mut self.id);
        id.clear();
        id.resize(w * h, 0);
        let mut next = 0u32;
        out.reset(w, h, 0);
        for (i, p) in points.as_slice().iter().enumerate() {
            if !is_valid_point(p) {
                continue;
            }
            let root = self.find(i);
            if id[root] == 0 {
                next += 1;
                id[root] = next;
            }
            out.as_mut_slice()[i] = id[root];
        }
        self.id = id;
    }
}
