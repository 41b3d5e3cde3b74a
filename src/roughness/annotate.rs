//! Roughness ground truth, annotation spec v1 (DESIGN.md): segments, boundary mask, edge
//! weights, the surface term `|n·(p − c)|` (Eq. 1) and the edge transient.

use rayon::prelude::*;
use serde::{Deserialize, Serialize};

use super::RoughnessError;
use crate::geometry::camera::{is_valid_point, PointMap};
use crate::geometry::normals::{local_planes, window_centroids, Neighbourhood};
use crate::geometry::plane::orient_towards_camera;
use crate::geometry::Plane;
use crate::geometry::{Grid, Intrinsics, Vec3, INVALID_POINT};

/// Parameters of annotation spec v1, with the spec's defaults.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct AnnotateConfig {
    /// Geometric resolution ε, metres (0.015).
    pub epsilon_m: f64,
    /// Neighbourhood of the surface term and of LS normals (R = 0.05 m, half-width cap 7 px).
    pub hood: Neighbourhood,
    /// Largest normal angle within one segment, degrees (10).
    pub segment_angle_deg: f64,
    /// Edge band σ, pixels (1.5).
    pub edge_sigma_px: f64,
}

impl Default for AnnotateConfig {
    fn default() -> Self {
        Self {
            epsilon_m: 0.015,
            hood: Neighbourhood::default(),
            segment_angle_deg: 10.0,
            edge_sigma_px: 1.5,
        }
    }
}

/// What the annotator consumes. Depth in metres (≤ 0 or non-finite: no data).
#[derive(Debug, Clone, Copy)]
pub struct AnnotateInput<'a> {
    /// Depth map, metres.
    pub depth_m: &'a Grid<f64>,
    /// Camera intrinsics for this depth map.
    pub intrinsics: &'a Intrinsics,
    /// Optional unit normals (camera frame); LS normals over the same radius stand in otherwise.
    pub normals: Option<&'a Grid<Vec3>>,
    /// Optional semantic labels (0 = void, treated as no data); one label for all otherwise.
    pub labels: Option<&'a Grid<u32>>,
}

/// Everything the annotator produces, per pixel.
#[derive(Debug, Clone, PartialEq)]
pub struct Annotation {
    /// Roughness r, metres (NaN: invalid).
    pub roughness_m: Grid<f64>,
    /// Boundary mask B.
    pub boundary: Grid<bool>,
    /// Edge weight W, metres (0 off boundaries).
    pub edge_weight_m: Grid<f64>,
    /// Segment ids, 1-based and compact (0: invalid).
    pub segments: Grid<u32>,
    /// The normals used (given or LS), NaN where none.
    pub normals: Grid<Vec3>,
    /// Surface term s, metres.
    pub surface_m: Grid<f64>,
    /// Edge transient ẽ, metres.
    pub edge_m: Grid<f64>,
}

/// Runs annotation spec v1 on one frame.
pub fn annotate(
    input: &AnnotateInput<'_>,
    cfg: &AnnotateConfig,
) -> Result<Annotation, RoughnessError> {
    let points = checked_points(input)?;
    let fx = input.intrinsics.fx_px;
    let (normals, centroids) = match input.normals {
        Some(n) => (
            oriented_normals(n, &points),
            window_centroids(&points, fx, &cfg.hood),
        ),
        None => {
            let planes = local_planes(&points, fx, &cfg.hood);
            (planes.normal, planes.centroid)
        }
    };
    let mut maps = SpecMaps::default();
    let mut roughness_m = Grid::default();
    let planes = SpecPlanes {
        points: &points,
        normals: &normals,
        centroids: &centroids,
    };
    spec_roughness_into(&planes, input.labels, cfg, &mut maps, &mut roughness_m);
    Ok(Annotation {
        roughness_m,
        boundary: maps.boundary,
        edge_weight_m: maps.edge_weight_m,
        segments: maps.segments,
        normals,
        surface_m: maps.surface_m,
        edge_m: maps.edge_m,
    })
}

/// The per-pixel local planes the spec's steps 2–7 start from, at one size: points (camera
/// frame, invalid where no data), unit normals facing the camera and the centroids of Eq. 1.
#[derive(Debug, Clone, Copy)]
pub struct SpecPlanes<'a> {
    /// Back-projected points.
    pub points: &'a PointMap,
    /// Unit normals (NaN: none).
    pub normals: &'a Grid<Vec3>,
    /// Local-plane centroids (the window means of spec step 5).
    pub centroids: &'a PointMap,
}

/// The maps of spec steps 2–6, kept from frame to frame so that a caller that reuses them
/// allocates nothing once they have reached the frame's size.
#[derive(Debug, Clone, Default)]
pub struct SpecMaps {
    /// Segment ids, 1-based and compact (0: invalid).
    pub segments: Grid<u32>,
    /// Boundary mask B.
    pub boundary: Grid<bool>,
    /// Edge weight W, metres (0 off boundaries).
    pub edge_weight_m: Grid<f64>,
    /// Surface term s (Eq. 1), metres; NaN where the pixel has no point or no normal.
    pub surface_m: Grid<f64>,
    /// Edge transient ẽ, metres (0 at invalid pixels).
    pub edge_m: Grid<f64>,
    forest: DisjointSets,
    edges: EdgeRows,
}

/// Spec v1 steps 2–7 from local planes: segments, boundary, edge weights, the surface term
/// (Eq. 1), the edge term and its transient, and `r = max(s, ẽ)` into `roughness_m` (NaN at
/// pixels without a point). This is what `tre annotate` and the `geometric` mode both run.
///
/// ```
/// use tre::geometry::{local_planes, Grid, Intrinsics, Neighbourhood};
/// use tre::roughness::annotate::{spec_roughness_into, AnnotateConfig, SpecMaps, SpecPlanes};
/// // A 10 cm drop between two floor halves seen from above.
/// let k = Intrinsics::from_hfov(40, 30, 60.0).unwrap();
/// let depth = Grid::from_fn(40, 30, |x, _| if x < 20 { 1.0 } else { 1.1 });
/// let points = k.back_project_map(&depth);
/// let planes = local_planes(&points, k.fx_px, &Neighbourhood::default());
/// let (mut maps, mut r) = (SpecMaps::default(), Grid::default());
/// let input = SpecPlanes { points: &points, normals: &planes.normal, centroids: &planes.centroid };
/// spec_roughness_into(&input, None, &AnnotateConfig::default(), &mut maps, &mut r);
/// assert!(r[(20, 15)] >= 0.1, "the drop is a hazard: {}", r[(20, 15)]);
/// assert!(r[(5, 15)] < 1e-6, "flat floor away from it: {}", r[(5, 15)]);
/// ```
pub fn spec_roughness_into(
    planes: &SpecPlanes<'_>,
    labels: Option<&Grid<u32>>,
    cfg: &AnnotateConfig,
    maps: &mut SpecMaps,
    roughness_m: &mut Grid<f64>,
) {
    let points = planes.points;
    let (w, h) = points.size();
    segment_into(
        points,
        planes.normals,
        labels,
        cfg,
        &mut maps.forest,
        &mut maps.segments,
    );
    boundary_mask_into(points, &maps.segments, &mut maps.boundary);
    edge_weights_into(points, &maps.boundary, &mut maps.edge_weight_m);
    maps.edges.collect(&maps.edge_weight_m, cfg.epsilon_m);
    maps.edges
        .transient_into(points, cfg.edge_sigma_px, &mut maps.edge_m);
    maps.surface_m.reset(w, h, f64::NAN);
    surface_term_into(
        points,
        planes.normals,
        planes.centroids,
        &mut maps.surface_m,
    );
    roughness_m.reset(w, h, f64::NAN);
    let (s, e) = (&maps.surface_m, &maps.edge_m);
    roughness_m.par_rows_mut().for_each(|(y, row)| {
        for (x, r) in row.iter_mut().enumerate() {
            if is_valid_point(&points[(x, y)]) {
                // A missing surface term (NaN) leaves the edge transient, which is ≥ 0.
                *r = s[(x, y)].max(e[(x, y)]);
            }
        }
    });
}

/// Back-projects the depth after checking sizes and that some data is there; void labels
/// become no data.
fn checked_points(input: &AnnotateInput<'_>) -> Result<PointMap, RoughnessError> {
    let size = input.depth_m.size();
    for (what, other) in [
        ("normals", input.normals.map(Grid::size)),
        ("labels", input.labels.map(Grid::size)),
    ] {
        if let Some(other) = other.filter(|o| *o != size) {
            return Err(RoughnessError::SizeMismatch {
                what,
                depth: size,
                other,
            });
        }
    }
    let mut points = input.intrinsics.back_project_map(input.depth_m);
    if let Some(labels) = input.labels {
        for (p, &l) in points.as_mut_slice().iter_mut().zip(labels.as_slice()) {
            if l == 0 {
                *p = INVALID_POINT;
            }
        }
    }
    if !points.as_slice().iter().any(is_valid_point) {
        return Err(RoughnessError::NoValidDepth {
            width: size.0,
            height: size.1,
        });
    }
    if let Some(normals) = input.normals {
        let lacking = |(p, n): (&Vec3, &Vec3)| is_valid_point(p) && !is_usable_normal(n.norm());
        let pairs = || points.as_slice().iter().zip(normals.as_slice());
        if let Some(i) = pairs().position(lacking) {
            return Err(RoughnessError::MissingNormals {
                missing: pairs().filter(|&pn| lacking(pn)).count(),
                valid: points
                    .as_slice()
                    .iter()
                    .filter(|p| is_valid_point(p))
                    .count(),
                first: (i % size.0, i / size.0),
            });
        }
    }
    Ok(points)
}

/// Whether a given normal of length `len` can be normalised (finite, not zero).
fn is_usable_normal(len: f64) -> bool {
    len > 0.0 && len.is_finite()
}

/// Normalises given normals and turns them towards the camera (invalid where not finite).
fn oriented_normals(normals: &Grid<Vec3>, points: &PointMap) -> Grid<Vec3> {
    Grid::par_from_fn(points.width(), points.height(), |x, y| {
        let (n, p) = (normals[(x, y)], points[(x, y)]);
        let len = n.norm();
        if is_valid_point(&p) && is_usable_normal(len) {
            orient_towards_camera(&(n / len), &p)
        } else {
            INVALID_POINT
        }
    })
}

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
const BAND_ROWS: usize = 32;

/// [`segment`] into `out`, with `forest` as scratch (both reused across frames). Bands of rows
/// join their own pixels in parallel; the joins across band borders follow; the partition is
/// the same as one pass gives, since components do not depend on the order of unions.
fn segment_into(
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
struct Joiner<'a> {
    points: &'a [Vec3],
    normals: &'a [Vec3],
    labels: Option<&'a [u32]>,
    cos_max: f64,
    epsilon_m: f64,
}

impl<'a> Joiner<'a> {
    fn new(
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

    fn joins(&self, i: usize, j: usize) -> bool {
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
struct DisjointSets {
    parent: Vec<u32>,
    size: Vec<u32>,
    id: Vec<u32>,
}

/// Union-find over a contiguous range of the pixels (`offset ..`), on slices of a
/// [`DisjointSets`]' arrays: parents hold whole-frame indices.
struct SetsView<'a> {
    parent: &'a mut [u32],
    size: &'a mut [u32],
    offset: usize,
}

impl SetsView<'_> {
    fn find(&mut self, i: usize) -> usize {
        let off = self.offset;
        let mut i = i as u32;
        while self.parent[i as usize - off] != i {
            let up = self.parent[self.parent[i as usize - off] as usize - off];
            self.parent[i as usize - off] = up;
            i = up;
        }
        i as usize
    }

    fn union(&mut self, a: usize, b: usize) {
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
    fn reset(&mut self, n: usize) {
        self.parent.clear();
        self.parent.extend(0..n as u32);
        self.size.clear();
        self.size.resize(n, 1);
    }

    fn view(&mut self) -> SetsView<'_> {
        SetsView {
            parent: &mut self.parent,
            size: &mut self.size,
            offset: 0,
        }
    }

    fn find(&mut self, i: usize) -> usize {
        self.view().find(i)
    }

    fn union(&mut self, a: usize, b: usize) {
        self.view().union(a, b);
    }

    /// Numbers the components 1, 2, … in raster order of their first pixel into `out`;
    /// invalid pixels get 0.
    fn compact_ids(&mut self, points: &PointMap, out: &mut Grid<u32>) {
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

/// The valid 8-neighbours of `(x, y)`, as flat indices.
fn neighbours8(w: usize, h: usize, x: usize, y: usize) -> impl Iterator<Item = usize> {
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
fn boundary_mask_into(points: &PointMap, segments: &Grid<u32>, out: &mut Grid<bool>) {
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
fn edge_weights_into(points: &PointMap, boundary: &Grid<bool>, out: &mut Grid<f64>) {
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

/// Step 4's edge term: W where W ≥ ε, 2W where 0.5ε < W < ε, else 0.
///
/// ```
/// use tre::roughness::annotate::edge_term;
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
/// use tre::geometry::{Grid, Vec3};
/// use tre::roughness::annotate::surface_term_into;
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
struct EdgeRows {
    /// `(x, e_x)` of each row's pixels with `e > 0`, rows one after another.
    terms: Vec<(u32, f64)>,
    /// Where each row's terms start in `terms` (height + 1 entries).
    row_start: Vec<usize>,
}

impl EdgeRows {
    /// The edge terms (step 4) of the edge weights `w_m`.
    fn collect(&mut self, w_m: &Grid<f64>, epsilon_m: f64) {
        self.gather(w_m, |w| edge_term(w, epsilon_m));
    }

    /// Edge terms given as a map.
    fn collect_terms(&mut self, e: &Grid<f64>) {
        self.gather(e, |e| e);
    }

    fn gather(&mut self, grid: &Grid<f64>, term: impl Fn(f64) -> f64) {
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
    fn transient_into(&self, points: &PointMap, sigma_px: f64, out: &mut Grid<f64>) {
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
struct TransientKernel {
    /// `⌊3σ⌋`: the largest offset along an axis.
    reach: usize,
    /// Per |dy|: the largest |dx| within 3σ, and the weights of dx = −reach ..= reach (0
    /// outside the disc).
    rows: Vec<(usize, Vec<f64>)>,
}

impl TransientKernel {
    fn new(sigma_px: f64) -> Self {
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
    fn row(&self, dy: usize) -> (usize, &[f64]) {
        let (half, weights) = &self.rows[dy];
        (*half, weights)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Step 6 as the spec writes it, pixel by pixel: the reference for the sparse kernel.
    fn transient_reference(edge: &Grid<f64>, points: &PointMap, sigma_px: f64) -> Grid<f64> {
        let (w, h) = edge.size();
        let reach = (3.0 * sigma_px).floor() as isize;
        Grid::from_fn(w, h, |x, y| {
            if !is_valid_point(&points[(x, y)]) {
                return 0.0;
            }
            let mut best: f64 = 0.0;
            for dy in -reach..=reach {
                for dx in -reach..=reach {
                    let d2 = (dx * dx + dy * dy) as f64;
                    let (nx, ny) = (x as isize + dx, y as isize + dy);
                    let inside = nx >= 0 && ny >= 0 && (nx as usize) < w && (ny as usize) < h;
                    if d2 > 9.0 * sigma_px * sigma_px || !inside {
                        continue;
                    }
                    let e = edge[(nx as usize, ny as usize)];
                    if e > 0.0 {
                        best = best.max(e * (-d2 / (2.0 * sigma_px * sigma_px)).exp());
                    }
                }
            }
            best
        })
    }

    #[test]
    fn sparse_transient_equals_the_per_pixel_definition_bit_for_bit() {
        let (w, h) = (53, 37);
        // Scattered edge terms of varied size, a hole pattern, edges on the frame's border.
        let edge = Grid::from_fn(w, h, |x, y| match (x * 7 + y * 13) % 29 {
            0 => 0.01 + 0.003 * (x % 5) as f64,
            3 if x == 0 || y == h - 1 => 0.2,
            _ if x == w - 1 && y % 4 == 0 => 0.05,
            _ => 0.0,
        });
        let points = Grid::from_fn(w, h, |x, y| {
            if (x * 3 + y * 5) % 11 == 0 {
                INVALID_POINT
            } else {
                Vec3::new(x as f64, y as f64, 2.0)
            }
        });
        for sigma in [0.4, 1.0, 1.5, 2.2] {
            let got = edge_transient(&edge, &points, sigma);
            let want = transient_reference(&edge, &points, sigma);
            let same = got
                .as_slice()
                .iter()
                .zip(want.as_slice())
                .all(|(a, b)| a.to_bits() == b.to_bits());
            assert!(same, "σ = {sigma}");
            assert!(got.as_slice().iter().filter(|&&v| v > 0.0).count() > w * h / 20);
        }
    }

    #[test]
    fn segments_do_not_depend_on_how_rows_are_split() {
        // Two planes meeting at a crease, with holes: the partition into segments is the
        // same as one pass over the whole frame would give.
        let k = Intrinsics::from_hfov(61, 203, 60.0).unwrap();
        let depth = Grid::from_fn(61, 203, |x, y| {
            if (x * 5 + y) % 17 == 0 {
                0.0
            } else {
                1.5 + 0.004 * (x as f64 - 30.0).abs() + 0.2 * ((y / 40) % 2) as f64
            }
        });
        let points = k.back_project_map(&depth);
        let planes = local_planes(&points, k.fx_px, &Neighbourhood::default());
        let cfg = AnnotateConfig::default();
        let got = segment(&points, &planes.normal, None, &cfg);
        let want = segment_serial(&points, &planes.normal, &cfg);
        assert_eq!(got, want);
        assert!(got.as_slice().iter().max().copied().unwrap_or(0) >= 5);
    }

    /// Step 2 in one serial pass (the reference for the banded union-find).
    fn segment_serial(points: &PointMap, normals: &Grid<Vec3>, cfg: &AnnotateConfig) -> Grid<u32> {
        let (w, h) = points.size();
        let joiner = Joiner::new(points, normals, None, cfg);
        let mut forest = DisjointSets::default();
        forest.reset(w * h);
        for y in 0..h {
            for x in 0..w {
                let i = y * w + x;
                if x + 1 < w && joiner.joins(i, i + 1) {
                    forest.union(i, i + 1);
                }
                if y + 1 < h && joiner.joins(i, i + w) {
                    forest.union(i, i + w);
                }
            }
        }
        let mut out = Grid::default();
        forest.compact_ids(points, &mut out);
        out
    }
}
