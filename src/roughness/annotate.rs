//! Roughness ground truth, annotation spec v1 (DESIGN.md): segments, boundary mask, edge
//! weights, the surface term `|n·(p − c)|` (Eq. 1) and the edge transient.

use rayon::prelude::*;
use serde::{Deserialize, Serialize};

use super::RoughnessError;
use crate::geometry::camera::{is_valid_point, PointMap};
use crate::geometry::normals::{local_planes, window_centroids, Neighbourhood};
use crate::geometry::plane::orient_towards_camera;
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
    let segments = segment(&points, &normals, input.labels, cfg);
    let boundary = boundary_mask(&points, &segments);
    let edge_weight_m = edge_weights(&points, &boundary);
    let edge_term = edge_weight_m.map(|&w| edge_term(w, cfg.epsilon_m));
    let edge_m = edge_transient(&edge_term, &points, cfg.edge_sigma_px);
    let surface_m = surface_term(&points, &normals, &centroids);
    let roughness_m = Grid::par_from_fn(points.width(), points.height(), |x, y| {
        if is_valid_point(&points[(x, y)]) {
            surface_m[(x, y)].max(edge_m[(x, y)])
        } else {
            f64::NAN
        }
    });
    Ok(Annotation {
        roughness_m,
        boundary,
        edge_weight_m,
        segments,
        normals,
        surface_m,
        edge_m,
    })
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
    let (w, h) = points.size();
    let cos_max = cfg.segment_angle_deg.to_radians().cos();
    let label = |i: usize| labels.map_or(1, |l| l.as_slice()[i]);
    let joins = |i: usize, j: usize| {
        let (pi, pj) = (points.as_slice()[i], points.as_slice()[j]);
        let (ni, nj) = (normals.as_slice()[i], normals.as_slice()[j]);
        is_valid_point(&pi)
            && is_valid_point(&pj)
            && label(i) == label(j)
            && ni.dot(&nj) > cos_max
            && ni.dot(&(pj - pi)).abs() < cfg.epsilon_m
            && nj.dot(&(pi - pj)).abs() < cfg.epsilon_m
    };
    let mut forest = DisjointSets::new(w * h);
    for y in 0..h {
        for x in 0..w {
            let i = y * w + x;
            if x + 1 < w && joins(i, i + 1) {
                forest.union(i, i + 1);
            }
            if y + 1 < h && joins(i, i + w) {
                forest.union(i, i + w);
            }
        }
    }
    compact_ids(points, &mut forest)
}

/// Numbers the components 1, 2, … in raster order of their first pixel; invalid pixels get 0.
fn compact_ids(points: &PointMap, forest: &mut DisjointSets) -> Grid<u32> {
    let (w, h) = points.size();
    let mut id_of_root = vec![0u32; w * h];
    let mut next = 0u32;
    let mut out = Grid::new(w, h, 0u32);
    for i in 0..w * h {
        if !is_valid_point(&points.as_slice()[i]) {
            continue;
        }
        let root = forest.find(i);
        if id_of_root[root] == 0 {
            next += 1;
            id_of_root[root] = next;
        }
        out.as_mut_slice()[i] = id_of_root[root];
    }
    out
}

/// Union-find with path halving and union by size.
struct DisjointSets {
    parent: Vec<usize>,
    size: Vec<u32>,
}

impl DisjointSets {
    fn new(n: usize) -> Self {
        Self {
            parent: (0..n).collect(),
            size: vec![1; n],
        }
    }

    fn find(&mut self, mut i: usize) -> usize {
        while self.parent[i] != i {
            self.parent[i] = self.parent[self.parent[i]];
            i = self.parent[i];
        }
        i
    }

    fn union(&mut self, a: usize, b: usize) {
        let (mut ra, mut rb) = (self.find(a), self.find(b));
        if ra == rb {
            return;
        }
        if self.size[ra] < self.size[rb] {
            std::mem::swap(&mut ra, &mut rb);
        }
        self.parent[rb] = ra;
        self.size[ra] += self.size[rb];
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
    let (w, h) = points.size();
    let s = segments.as_slice();
    Grid::par_from_fn(w, h, |x, y| {
        let i = y * w + x;
        s[i] != 0 && neighbours8(w, h, x, y).any(|j| s[j] != 0 && s[j] != s[i])
    })
}

/// Step 4: on boundary pixels, the largest distance to a valid 8-neighbour; 0 elsewhere.
pub fn edge_weights(points: &PointMap, boundary: &Grid<bool>) -> Grid<f64> {
    let (w, h) = points.size();
    let p = points.as_slice();
    Grid::par_from_fn(w, h, |x, y| {
        let i = y * w + x;
        if !boundary.as_slice()[i] {
            return 0.0;
        }
        neighbours8(w, h, x, y)
            .filter(|&j| is_valid_point(&p[j]))
            .map(|j| (p[j] - p[i]).norm())
            .fold(0.0, f64::max)
    })
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

/// Step 5: `|n_i·(p_i − c_i)|` where normal and centroid exist; 0 where the normal is missing.
fn surface_term(points: &PointMap, normals: &Grid<Vec3>, centroids: &PointMap) -> Grid<f64> {
    Grid::par_from_fn(points.width(), points.height(), |x, y| {
        let (p, n, c) = (points[(x, y)], normals[(x, y)], centroids[(x, y)]);
        let s = n.dot(&(p - c)).abs();
        if s.is_finite() {
            s
        } else {
            0.0
        }
    })
}

/// Step 6: `ẽ_i = max_j e_j·exp(−d_ij²/2σ²)` over pixels j within 3σ (pixel distance), at valid i.
pub fn edge_transient(edge: &Grid<f64>, points: &PointMap, sigma_px: f64) -> Grid<f64> {
    let (w, h) = edge.size();
    let reach = (3.0 * sigma_px).floor() as isize;
    let mut out = Grid::new(w, h, 0.0);
    out.par_rows_mut().for_each(|(y, row)| {
        for (x, o) in row.iter_mut().enumerate() {
            if !is_valid_point(&points[(x, y)]) {
                continue;
            }
            *o = transient_at(edge, x, y, reach, sigma_px);
        }
    });
    out
}

fn transient_at(edge: &Grid<f64>, x: usize, y: usize, reach: isize, sigma_px: f64) -> f64 {
    let (w, h) = edge.size();
    let mut best: f64 = 0.0;
    for dy in -reach..=reach {
        for dx in -reach..=reach {
            let d2 = (dx * dx + dy * dy) as f64;
            let (nx, ny) = (x as isize + dx, y as isize + dy);
            if d2 > 9.0 * sigma_px * sigma_px
                || nx < 0
                || ny < 0
                || nx as usize >= w
                || ny as usize >= h
            {
                continue;
            }
            let e = edge[(nx as usize, ny as usize)];
            if e > 0.0 {
                best = best.max(e * (-d2 / (2.0 * sigma_px * sigma_px)).exp());
            }
        }
    }
    best
}
