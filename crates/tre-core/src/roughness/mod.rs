//! Roughness: the ground-truth annotator (spec v1), the evaluation metrics, the hazard scores
//! of real frames, the sensor-noise uncertainty map and three-state traversability. Pure and
//! synchronous, like `geometry`.

pub mod annotate;
pub mod hazard;
pub mod interval;
pub mod metrics;
pub mod noise;
pub mod terrain;
pub mod traversal;

/// Errors of the roughness layer.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum RoughnessError {
    /// An input map whose size differs from the depth map's.
    #[error("{what} is {}×{} but the depth map is {}×{}", other.0, other.1, depth.0, depth.1)]
    SizeMismatch {
        /// Which input.
        what: &'static str,
        /// Depth size (w, h).
        depth: (usize, usize),
        /// The other input's size (w, h).
        other: (usize, usize),
    },
    /// A depth map with no valid pixel.
    #[error(
        "the {width}×{height} depth map has no valid pixel (all zero, negative or not finite)"
    )]
    NoValidDepth {
        /// Width.
        width: usize,
        /// Height.
        height: usize,
    },
    /// Given normals that are missing (not finite, or of zero length) at pixels with data.
    #[error(
        "normals: {missing} of the {valid} pixels with depth have no normal (not finite or of \
         zero length), the first at x = {}, y = {}; give normals for every pixel with depth, \
         mark the others void (label 0), or leave the normals out (LS normals stand in)",
        first.0,
        first.1
    )]
    MissingNormals {
        /// Pixels with depth and no normal.
        missing: usize,
        /// Pixels with depth.
        valid: usize,
        /// The first of them (x, y), in row order.
        first: (usize, usize),
    },
    /// A setting that must be a positive number (named by its `tre annotate` option).
    #[error("{option} must be positive, got {value}")]
    NotPositive {
        /// The option, such as `--epsilon-m`.
        option: &'static str,
        /// What it was given.
        value: f64,
    },
}
