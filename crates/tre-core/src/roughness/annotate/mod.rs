//! Roughness ground truth, annotation spec v1 (docs/design.md): segments, boundary mask, edge
//! weights, the surface term `|n·(p − c)|` (Eq. 1) and the edge transient.

use rayon::prelude::*;
use serde::{Deserialize, Serialize};

use super::RoughnessError;
use crate::geometry::normals::{local_planes, window_centroids, Neighbourhood};
use crate::geometry::orient_towards_camera;
use crate::geometry::Plane;
use crate::geometry::{is_valid_point, PointMap};
use crate::geometry::{Grid, Intrinsics, Vec3, INVALID_POINT};

/// Parameters of annotation spec v1, with the spec's defaults: ε 0.015 m, R 0.05 m, half-width
/// cap 7 px, segment angle 10°, edge band σ 1.5 px. The first three are options of
/// `tre annotate` (clap's, behind the `cli` feature).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[cfg_attr(feature = "cli", derive(clap::Args))]
pub struct AnnotateConfig {
    /// Geometric resolution ε, metres.
    #[cfg_attr(feature = "cli", arg(long, default_value_t = 0.015))]
    pub epsilon_m: f64,
    /// Neighbourhood of the surface term and of LS normals.
    #[cfg_attr(feature = "cli", command(flatten))]
    pub hood: Neighbourhood,
    /// Largest normal angle within one segment, degrees.
    #[cfg_attr(feature = "cli", arg(skip = AnnotateConfig::default().segment_angle_deg))]
    pub segment_angle_deg: f64,
    /// Edge band σ, pixels.
    #[cfg_attr(feature = "cli", arg(skip = AnnotateConfig::default().edge_sigma_px))]
    pub edge_sigma_px: f64,
}

impl AnnotateConfig {
    /// The settings checked, with a window half-width cap of at least 1 pixel.
    ///
    /// # Errors
    ///
    /// [`RoughnessError::NotPositive`] for an ε or a radius that is not a positive number.
    pub fn checked(mut self) -> Result<Self, RoughnessError> {
        for (option, value) in [
            ("--epsilon-m", self.epsilon_m),
            ("--radius-m", self.hood.radius_m),
        ] {
            if !(value.is_finite() && value > 0.0) {
                return Err(RoughnessError::NotPositive { option, value });
            }
        }
        self.hood.max_half_width = self.hood.max_half_width.max(1);
        Ok(self)
    }
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

impl<'a> AnnotateInput<'a> {
    /// A depth map alone: LS normals over the spec's radius and one label for all, as
    /// `tre annotate` reads a depth image.
    #[must_use]
    pub fn depth(depth_m: &'a Grid<f64>, intrinsics: &'a Intrinsics) -> Self {
        Self {
            depth_m,
            intrinsics,
            normals: None,
            labels: None,
        }
    }
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
/// use tre_core::geometry::normals::{local_planes, Neighbourhood};
/// use tre_core::geometry::{Grid, Intrinsics};
/// use tre_core::roughness::annotate::{spec_roughness_into, AnnotateConfig, SpecMaps, SpecPlanes};
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

mod boundary;
mod segments;
mod terms;
#[cfg(test)]
mod tests;

pub use boundary::{boundary_mask, edge_weights};
use boundary::{boundary_mask_into, edge_weights_into};
pub use segments::segment;
use segments::{segment_into, DisjointSets};
use terms::EdgeRows;
pub use terms::{edge_term, edge_transient, surface_term_into};
