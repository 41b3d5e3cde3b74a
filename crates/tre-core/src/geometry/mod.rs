//! Geometry core: pinhole camera, gravity frame, least-squares planes and normals, Eq. 1, and the
//! DSAC hypothesis sampler. Pure and synchronous (rayon for row-parallel kernels only).

mod camera;
pub mod dsac;
pub mod fastmath;
pub mod floor;
mod gravity;
mod grid;
pub mod hash;
pub(crate) mod neighbours;
pub mod normals;
mod plane;
pub mod raycast;
pub mod simd;
pub mod sums;

pub use camera::{
    depth_of, is_valid_point, Intrinsics, PointMap, INVALID_POINT, MAX_FOV_DEG, MIN_FOV_DEG,
};
pub use gravity::{slope_from_up, Mounting};
pub use grid::{Grid, NEIGHBOURS_8};
pub(crate) use plane::orient_towards_camera;
pub(crate) use plane::{covariance_lanes, eigen_plane, eigen_planes_of, SymLanes};
pub use plane::{Moments, Plane};

/// A 3-D vector or point in metres (f64: geometry where precision matters).
pub type Vec3 = nalgebra::Vector3<f64>;

/// Errors of the geometry layer.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum GeometryError {
    /// A buffer's length does not match the grid it should fill.
    #[error("buffer of {len} values cannot be a {width}×{height} grid")]
    BufferSize {
        /// Requested width.
        width: usize,
        /// Requested height.
        height: usize,
        /// Values supplied.
        len: usize,
    },
    /// A focal length that is not a positive finite number.
    #[error("focal length {name} must be positive and finite, got {value}")]
    BadFocalLength {
        /// `fx` or `fy`.
        name: &'static str,
        /// The value given.
        value: f64,
    },
    /// A principal point that is not finite.
    #[error("principal point {name} must be finite, got {value}")]
    BadPrincipalPoint {
        /// `cx` or `cy`.
        name: &'static str,
        /// The value given.
        value: f64,
    },
    /// A camera height stated without the pitch.
    #[error(
        "height_m is stated without pitch_deg: give the pitch too (degrees below the horizon), \
         or neither and gravity comes from the depth"
    )]
    HeightWithoutPitch,
    /// A pitch outside [−90°, 90°].
    #[error("camera pitch must be within [-90°, 90°], got {:.3}°", pitch_rad.to_degrees())]
    BadPitch {
        /// The value given, radians.
        pitch_rad: f64,
    },
    /// A negative or non-finite camera height.
    #[error("camera height must be finite and non-negative, got {height_m} m")]
    BadHeight {
        /// The value given, metres.
        height_m: f64,
    },
    /// Intrinsics that no pinhole camera could have for an image of the frame's size.
    #[error("intrinsics {what} cannot describe a {width}×{height} image: {}", what.rule())]
    ImplausibleIntrinsics {
        /// The image width, pixels.
        width: usize,
        /// The image height, pixels.
        height: usize,
        /// The value at fault, as given.
        what: ImplausibleIntrinsic,
    },
    /// Neighbour logits of the wrong size for the point map.
    #[error("neighbour logits hold {got} values, expected 49 × H × W = {expected}")]
    LogitsSize {
        /// 49 × H × W.
        expected: usize,
        /// Values supplied.
        got: usize,
    },
}

/// The intrinsic of [`GeometryError::ImplausibleIntrinsics`] at fault, as given; its `Display`
/// says which and its value (`cx = -1000000000`), [`rule`](Self::rule) what it breaks.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum ImplausibleIntrinsic {
    /// A principal point coordinate more than one image size off the image.
    PrincipalPoint {
        /// `cx` or `cy`.
        name: &'static str,
        /// The value given, pixels.
        value_px: f64,
    },
    /// A focal length whose field of view across the image is outside [`MIN_FOV_DEG`] to
    /// [`MAX_FOV_DEG`].
    FocalLength {
        /// `fx` or `fy`.
        name: &'static str,
        /// The value given, pixels.
        value_px: f64,
        /// The field of view it gives across the image, degrees.
        fov_deg: f64,
    },
}

impl ImplausibleIntrinsic {
    /// The rule the value breaks, in words.
    #[must_use]
    pub fn rule(&self) -> &'static str {
        match self {
            Self::PrincipalPoint { .. } => {
                "the principal point must lie within one image size of the image"
            }
            Self::FocalLength { .. } => {
                "the field of view must be 0.1° to 170° (is the focal length in pixels?)"
            }
        }
    }
}

impl std::fmt::Display for ImplausibleIntrinsic {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match *self {
            Self::PrincipalPoint { name, value_px } => write!(f, "{name} = {value_px}"),
            Self::FocalLength {
                name,
                value_px,
                fov_deg,
            } => write!(f, "{name} = {value_px} ({fov_deg:.3}° across the image)"),
        }
    }
}
