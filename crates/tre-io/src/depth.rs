//! Depth maps in metres: reading a 16-bit PNG at its scale or a float `.npy`, and the check
//! that refuses depth which cannot be one (no valid pixel, millimetres, a wrong scale).

use std::io::BufReader;
use std::path::Path;

use image::{DynamicImage, ImageBuffer};

use tre_core::geometry::Grid;

use super::npy::{self, NpyArray, NpyError};
use super::{is_npy, npy_grid, open, read_image, IoError};

/// Nearest median depth any sensor gives, metres: below it the depth scale is wrong.
pub const MIN_MEDIAN_DEPTH_M: f64 = 0.01;
/// Farthest median depth any robot's depth sensor gives, metres: above it the depth is in
/// millimetres, or the depth scale is wrong.
pub const MAX_MEDIAN_DEPTH_M: f64 = 200.0;

/// Why a depth map in metres cannot be one ([`check_depth`]).
#[derive(Debug, Clone, Copy, PartialEq, thiserror::Error)]
pub enum DepthError {
    /// Every pixel is zero, negative or not finite.
    #[error(
        "the {width}×{height} depth map has no valid pixel (all zero, negative or not finite)"
    )]
    NoValidPixel {
        /// Map width, pixels.
        width: usize,
        /// Map height, pixels.
        height: usize,
    },
    /// The median valid depth is beyond [`MAX_MEDIAN_DEPTH_M`].
    #[error(
        "the median depth is {median_m:.1} m, farther than any depth sensor sees: is the depth \
         in millimetres, or its depth scale (units per metre) wrong?"
    )]
    TooFar {
        /// The median valid depth, metres.
        median_m: f64,
    },
    /// The median valid depth is below [`MIN_MEDIAN_DEPTH_M`].
    #[error(
        "the median depth is {median_m:.2e} m, nearer than any depth sensor sees: is the depth \
         scale (units per metre) wrong?"
    )]
    TooNear {
        /// The median valid depth, metres.
        median_m: f64,
    },
}

/// Reads depth in metres: a 16-bit grey PNG divided by `units_per_m` (0 = no data), or a float
/// `.npy` already in metres (0 or NaN = no data). Depth that cannot be one ([`check_depth`]:
/// no valid pixel, or a median in millimetres) is refused.
pub fn read_depth(path: &Path, units_per_m: f64) -> Result<Grid<f64>, IoError> {
    let npy = is_npy(path);
    let depth = if npy {
        let npy_error = |reason: NpyError| IoError::Npy {
            path: path.to_owned(),
            reason,
        };
        let array = npy::read_npy(BufReader::new(open(path)?)).map_err(npy_error)?;
        npy_depth(array).map_err(npy_error)?
    } else {
        match read_image(path)? {
            DynamicImage::ImageLuma16(img) => depth_from_luma16(img, units_per_m),
            other => {
                return Err(IoError::ImageKind {
                    path: path.to_owned(),
                    expected: "depth must be a 16-bit grey PNG or a float .npy",
                    got: other.color(),
                })
            }
        }
    };
    check_depth(&depth).map_err(|reason| IoError::Depth {
        path: path.to_owned(),
        reason,
        units_per_m: (!npy).then_some(units_per_m),
    })?;
    Ok(depth)
}

/// Depth in metres from a decoded 16-bit grey image at `units_per_m` (0 = no data).
pub fn depth_from_luma16(
    img: ImageBuffer<image::Luma<u16>, Vec<u16>>,
    units_per_m: f64,
) -> Grid<f64> {
    let (w, h) = (img.width() as usize, img.height() as usize);
    let data = img
        .into_raw()
        .into_iter()
        .map(|v| f64::from(v) / units_per_m)
        .collect();
    Grid::from_vec(w, h, data).expect("decoder sizes agree; this is a bug")
}

/// Whether a depth map in metres can be one: some valid pixel (finite, positive), and a median
/// valid depth between [`MIN_MEDIAN_DEPTH_M`] and [`MAX_MEDIAN_DEPTH_M`], which catches depth
/// in millimetres or a wrong depth scale. The median is taken over at most about 16,000
/// evenly spread pixels (a fraction of a millisecond). For why not, an error whose message
/// says what to check.
///
/// ```
/// use tre_core::geometry::Grid;
/// use tre_io::DepthError;
/// assert!(tre_io::check_depth(&Grid::new(64, 48, 1.5)).is_ok());
/// let e = tre_io::check_depth(&Grid::new(64, 48, 0.0)).unwrap_err();
/// assert_eq!(e, DepthError::NoValidPixel { width: 64, height: 48 });
/// assert!(e.to_string().contains("no valid pixel"));
/// let e = tre_io::check_depth(&Grid::new(64, 48, 1500.0)).unwrap_err();
/// assert!(e.to_string().contains("millimetres"));
/// ```
pub fn check_depth(depth_m: &Grid<f64>) -> Result<(), DepthError> {
    let all = depth_m.as_slice();
    let step = (all.len() / 16_384).max(1);
    let mut sample: Vec<f64> = all
        .iter()
        .step_by(step)
        .copied()
        .filter(|d| d.is_finite() && *d > 0.0)
        .collect();
    if sample.is_empty() && !all.iter().any(|d| d.is_finite() && *d > 0.0) {
        let (width, height) = depth_m.size();
        return Err(DepthError::NoValidPixel { width, height });
    }
    if sample.is_empty() {
        return Ok(()); // Valid pixels, all between the sampled ones: too few to judge.
    }
    let mid = sample.len() / 2;
    let median_m = *sample.select_nth_unstable_by(mid, f64::total_cmp).1;
    if median_m > MAX_MEDIAN_DEPTH_M {
        return Err(DepthError::TooFar { median_m });
    }
    if median_m < MIN_MEDIAN_DEPTH_M {
        return Err(DepthError::TooNear { median_m });
    }
    Ok(())
}

/// Depth in metres from a `.npy`: a 2-D float array. Integer arrays are refused, since their
/// unit cannot be known (millimetres read as metres would be a thousand times off); the error
/// says what to send instead.
pub fn npy_depth(a: NpyArray) -> Result<Grid<f64>, NpyError> {
    if !a.is_float() {
        return Err(NpyError::DepthNotFloat { dtype: a.dtype });
    }
    npy_grid(a)
}
