//! Pinhole camera (OpenCV convention: x right, y down, z forward, metres): projection and the
//! back-projection of organised depth maps into point maps.

use nalgebra::Vector3;
use rayon::prelude::*;
use serde::{Deserialize, Serialize};

use super::{GeometryError, Grid, ImplausibleIntrinsic, Vec3};

/// Per-pixel 3-D points in the camera frame (metres); invalid pixels hold NaN.
pub type PointMap = Grid<Vec3>;

/// The point that marks a pixel without data.
pub const INVALID_POINT: Vec3 = Vector3::new(f64::NAN, f64::NAN, f64::NAN);

/// True when `p` is a real point in front of the camera.
pub fn is_valid_point(p: &Vec3) -> bool {
    p.z > 0.0 && p.z.is_finite() && p.x.is_finite() && p.y.is_finite()
}

/// The narrowest field of view across an image that [`Intrinsics::check_for`] accepts, degrees.
pub const MIN_FOV_DEG: f64 = 0.1;
/// The widest field of view across an image that [`Intrinsics::check_for`] accepts, degrees.
pub const MAX_FOV_DEG: f64 = 170.0;

/// Pinhole intrinsics in pixels of the frame they describe.
///
/// ```
/// use tre_core::geometry::Intrinsics;
/// let k = Intrinsics::new(500.0, 500.0, 320.0, 240.0).unwrap();
/// let p = k.back_project(420.0, 240.0, 2.0);
/// assert!((p.x - 0.4).abs() < 1e-12);
/// let (u, v) = k.project(&p).unwrap();
/// assert!((u - 420.0).abs() < 1e-9 && (v - 240.0).abs() < 1e-9);
/// ```
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Intrinsics {
    /// Focal length along x, pixels.
    pub fx_px: f64,
    /// Focal length along y, pixels.
    pub fy_px: f64,
    /// Principal point x, pixels.
    pub cx_px: f64,
    /// Principal point y, pixels.
    pub cy_px: f64,
}

impl Intrinsics {
    /// Checked intrinsics: focal lengths must be finite and positive, the principal point finite.
    pub fn new(fx_px: f64, fy_px: f64, cx_px: f64, cy_px: f64) -> Result<Self, GeometryError> {
        let k = Self {
            fx_px,
            fy_px,
            cx_px,
            cy_px,
        };
        k.validate()?;
        Ok(k)
    }

    /// Re-checks the invariants of [`Intrinsics::new`] (useful after deserialising).
    pub fn validate(&self) -> Result<(), GeometryError> {
        for (name, f) in [("fx", self.fx_px), ("fy", self.fy_px)] {
            if !(f.is_finite() && f > 0.0) {
                return Err(GeometryError::BadFocalLength { name, value: f });
            }
        }
        for (name, c) in [("cx", self.cx_px), ("cy", self.cy_px)] {
            if !c.is_finite() {
                return Err(GeometryError::BadPrincipalPoint { name, value: c });
            }
        }
        Ok(())
    }

    /// Checks that these intrinsics can describe a `width × height` image: the principal point
    /// within one image size of the image (`−w ≤ cx ≤ 2w`, the same for y: a crop may move it
    /// outside, never further), and a field of view across the image between
    /// [`MIN_FOV_DEG`] and [`MAX_FOV_DEG`] on each axis (a pinhole model of a wider lens would
    /// not be one). Values beyond these are typing errors or wrong units, and would turn into
    /// roughness of kilometres or of nothing at all. A focal length given in millimetres is
    /// caught when it is below 1/23 of the image side in pixels (3.6 mm on a 640-pixel image).
    ///
    /// ```
    /// use tre_core::geometry::Intrinsics;
    /// assert!(Intrinsics::new(525.0, 525.0, 319.5, 239.5).unwrap().check_for(640, 480).is_ok());
    /// assert!(Intrinsics::new(525.0, 525.0, -1e9, 239.5).unwrap().check_for(640, 480).is_err());
    /// assert!(Intrinsics::new(1e-9, 525.0, 319.5, 239.5).unwrap().check_for(640, 480).is_err());
    /// ```
    pub fn check_for(&self, width: usize, height: usize) -> Result<(), GeometryError> {
        let fault = |what| GeometryError::ImplausibleIntrinsics {
            width,
            height,
            what,
        };
        for (name, c, side) in [("cx", self.cx_px, width), ("cy", self.cy_px, height)] {
            let side = side as f64;
            if !(-side..=2.0 * side).contains(&c) {
                return Err(fault(ImplausibleIntrinsic::PrincipalPoint {
                    name,
                    value_px: c,
                }));
            }
        }
        for (name, f, side) in [("fx", self.fx_px, width), ("fy", self.fy_px, height)] {
            let fov_deg = 2.0 * (side as f64 / (2.0 * f)).atan().to_degrees();
            if !(MIN_FOV_DEG..=MAX_FOV_DEG).contains(&fov_deg) {
                return Err(fault(ImplausibleIntrinsic::FocalLength {
                    name,
                    value_px: f,
                    fov_deg,
                }));
            }
        }
        Ok(())
    }

    /// A camera with a horizontal field of view `hfov_deg`, square pixels and a centred
    /// principal point, for a `width × height` image.
    pub fn from_hfov(width: usize, height: usize, hfov_deg: f64) -> Result<Self, GeometryError> {
        let f = width as f64 / 2.0 / (hfov_deg.to_radians() / 2.0).tan();
        Self::new(f, f, width as f64 / 2.0 - 0.5, height as f64 / 2.0 - 0.5)
    }

    /// The same camera for an image resized by `sx` horizontally and `sy` vertically
    /// (pixel centres at integer coordinates).
    pub fn scaled(&self, sx: f64, sy: f64) -> Result<Self, GeometryError> {
        Self::new(
            self.fx_px * sx,
            self.fy_px * sy,
            (self.cx_px + 0.5) * sx - 0.5,
            (self.cy_px + 0.5) * sy - 0.5,
        )
    }

    /// The 3-D point seen at pixel `(u, v)` at depth `depth_m` (z, not range).
    pub fn back_project(&self, u: f64, v: f64, depth_m: f64) -> Vec3 {
        Vector3::new(
            (u - self.cx_px) / self.fx_px * depth_m,
            (v - self.cy_px) / self.fy_px * depth_m,
            depth_m,
        )
    }

    /// The pixel where `p` appears, or `None` for points not in front of the camera.
    pub fn project(&self, p: &Vec3) -> Option<(f64, f64)> {
        (p.z > 0.0 && p.z.is_finite()).then(|| {
            (
                self.fx_px * p.x / p.z + self.cx_px,
                self.fy_px * p.y / p.z + self.cy_px,
            )
        })
    }

    /// Back-projects an organised depth map (metres; 0, negative or non-finite = no data)
    /// into a point map of the same size. Invalid pixels stay invalid.
    pub fn back_project_map(&self, depth_m: &Grid<f64>) -> PointMap {
        let mut out = PointMap::default();
        self.back_project_map_into(depth_m, &mut out);
        out
    }

    /// [`back_project_map`](Self::back_project_map) into `out`, which takes the depth map's size
    /// and keeps its buffer (for maps reused from frame to frame).
    ///
    /// ```
    /// use tre_core::geometry::{is_valid_point, Grid, Intrinsics, PointMap};
    /// let k = Intrinsics::from_hfov(4, 3, 60.0).unwrap();
    /// let mut points = PointMap::default();
    /// k.back_project_map_into(&Grid::new(4, 3, 2.0), &mut points);
    /// k.back_project_map_into(&Grid::new(2, 2, 0.0), &mut points);
    /// assert_eq!(points.size(), (2, 2));
    /// assert!(!points.as_slice().iter().any(is_valid_point));
    /// ```
    pub fn back_project_map_into(&self, depth_m: &Grid<f64>, out: &mut PointMap) {
        let (w, h) = depth_m.size();
        out.reset(w, h, INVALID_POINT);
        out.par_rows_mut().for_each(|(y, row)| {
            for (x, p) in row.iter_mut().enumerate() {
                let z = depth_m[(x, y)];
                if z > 0.0 && z.is_finite() {
                    *p = self.back_project(x as f64, y as f64, z);
                }
            }
        });
    }
}

/// The depth (z) of every point; invalid points give 0.
pub fn depth_of(points: &PointMap) -> Grid<f64> {
    points.map(|p| if is_valid_point(p) { p.z } else { 0.0 })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn implausible_intrinsics_say_which_value_and_the_rule() {
        let k = |fx, cx| Intrinsics::new(fx, 525.0, cx, 239.5).expect("finite");
        let off = k(525.0, -1e9).check_for(640, 480).expect_err("far off");
        assert_eq!(
            off.to_string(),
            "intrinsics cx = -1000000000 cannot describe a 640×480 image: the principal point \
             must lie within one image size of the image"
        );
        let mm = k(3.6, 319.5).check_for(640, 480).expect_err("millimetres");
        assert_eq!(
            mm.to_string(),
            "intrinsics fx = 3.6 (178.711° across the image) cannot describe a 640×480 image: \
             the field of view must be 0.1° to 170° (is the focal length in pixels?)"
        );
    }
}
