//! The robot's map: a gravity-aligned grid of cells fused over frames (docs/map.md).
//!
//! The map frame is the world frame of the poses turned so that its z axis is gravity's up
//! ([`MapFrame`]); cells are `cell_m` squares of that frame's x–y plane. The grid covers a
//! square of `side` cells around a centre that follows the robot: storage is a ring buffer
//! indexed by world cell modulo the side, so recentring clears only the rows and columns that
//! leave the window ([`GridMap::recentre`]) and never copies the grid.
//!
//! Each cell keeps two surfaces ([`Cell`]): the ground, the lowest surface seen, whose height
//! a scalar Kalman filter fuses frame after frame, and the highest surface seen above it (a
//! counter top, an overhang), kept apart so that it does not pull the ground up. Roughness,
//! slope and step are read from the fused ground heights of a neighbourhood of cells
//! ([`GridMap::layers`]), as elevation mappers do: the sensor's noise averages out over the
//! views while a real step stays. [`MapSession`] is the one way a caller (`tre map`, the
//! stream, the ROS 2 node) starts, fuses and reads a map; [`MapParams`] its settings file.

mod cell;
mod grid;
mod layers;
mod params;
mod pose;
mod session;
mod surface;

pub use cell::{Cell, Fused};
pub use grid::{FuseStats, GridMap};
pub use layers::{Layers, MapLimits, LAYER_NAMES, LAYER_UNITS};
pub use params::{
    FusionKeys, GridKeys, MapParams, MapParamsFile, MapPreset, ParamsError, RangeKeys,
    TraversabilityKeys,
};
pub use pose::{MapFrame, Pose};
pub use session::{GravitySource, MapSession, SessionFrame};

/// How a map is laid out.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MapConfig {
    /// Side of a cell, metres (default 0.04).
    pub cell_m: f64,
    /// Cells along each side of the square window (default 200: 8 m at 4 cm).
    pub side: usize,
    /// Process noise of a cell's height, m² per second (the world changes slowly).
    pub process_var_per_s: f64,
    /// Innovations beyond this many standard deviations are outliers (default 3).
    pub outlier_sigmas: f64,
    /// Outliers in a row after which a cell restarts from the new measurement (default 3).
    pub restart_after: u32,
    /// Points beyond this depth are left out, metres (default 4).
    pub max_range_m: f64,
    /// Points nearer than this depth are left out, metres (default 0: none).
    pub min_range_m: f64,
    /// A cell's points within this height of its lowest point are one surface, metres
    /// (default 0.05; three height σ when more).
    pub surface_band_m: f64,
    /// The least height σ of a measurement, metres: what the depth's noise model leaves out
    /// (pose and calibration error; default 0.005).
    pub height_floor_m: f64,
    /// Radius of the neighbourhood of cells whose fused heights give a cell's roughness and
    /// slope, metres (default 0.1).
    pub roughness_radius_m: f64,
}

impl Default for MapConfig {
    fn default() -> Self {
        Self {
            cell_m: 0.04,
            side: 200,
            process_var_per_s: 1e-6,
            outlier_sigmas: 3.0,
            restart_after: 3,
            max_range_m: 4.0,
            min_range_m: 0.0,
            surface_band_m: 0.05,
            height_floor_m: 0.005,
            roughness_radius_m: 0.1,
        }
    }
}

/// Why a frame was not fused; the map keeps what it had.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum MapError {
    /// A pose whose rotation is not a rotation (or not finite).
    #[error(
        "the pose is not a rigid transform (rotation off by {error:.2e}: RᵀR must be I, det R = 1, \
         the last row 0 0 0 1)"
    )]
    NotRigid {
        /// Largest deviation found.
        error: f64,
    },
    /// The camera is farther from the map's centre than the map can follow in one step.
    #[error(
        "the camera is {distance_m:.1} m from the map's centre, beyond {limit_m:.1} m: a pose in \
         another frame or a jump; skipped"
    )]
    TooFar {
        /// The distance, metres.
        distance_m: f64,
        /// The largest accepted, metres.
        limit_m: f64,
    },
    /// No point of the frame fell in the map.
    #[error("the frame has no valid point within range of the map; skipped")]
    NothingSeen,
    /// A gravity direction of zero length (or not finite).
    #[error("map configuration: gravity {0:?} has no direction")]
    NoGravityDirection([f64; 3]),
    /// A cell size that is not positive, or a side outside 1 to 8192 cells.
    #[error(
        "map configuration: cell {cell_m} m and side {side} cells: the cell must be positive and \
         the side 1 to 8192"
    )]
    BadGrid {
        /// Cell side, metres.
        cell_m: f64,
        /// Cells per side.
        side: usize,
    },
    /// No gravity was given or stated and the first frame shows no ground to level by.
    #[error("no gravity given, no pitch stated, and no ground in the first frame")]
    NoGround,
    /// No gravity was given or stated and the first frame's ground fit is not confident.
    #[error(
        "no gravity given, no pitch stated, and the first frame's ground fit is not confident \
         ({:.1}% of the points on it): the map cannot be levelled", 100.0 * support
    )]
    GroundNotConfident {
        /// Share of the valid points on the fitted plane.
        support: f64,
    },
}

#[cfg(test)]
mod tests;
