//! A raw, distorted image remapped into the pinhole of its camera_info's `p` (`tre ros2
//! --undistort`), as image_proc's rectify does (OpenCV's `initUndistortRectifyMap` with `k`,
//! `d`, `r`, `p`), but nearest-neighbour, so that no depth is blended across an edge.
//!
//! A rectified pixel's ray is `p`'s; `r` turns it into the raw camera's frame, the distortion
//! model `d` moves it to where the lens put it, and `k` gives the raw pixel read there. A depth
//! is the raw camera's z; with a rectification rotation `r` it becomes the rectified camera's.

use image::RgbImage;
use nalgebra::Matrix3;
use tre_core::geometry::{Grid, Intrinsics};
use tre_record::msgs::CameraInfo;

use crate::error::InputError;

/// For each pixel of the rectified image, the raw pixel it reads and the factor from the raw
/// camera's z to the rectified one's.
#[derive(Debug, Clone)]
pub struct Rectifier {
    /// The camera_info it was made for.
    info: CameraInfo,
    /// Raw pixel index per rectified pixel; `u32::MAX` where the ray leaves the raw image.
    source: Vec<u32>,
    /// z_rectified / z_raw per rectified pixel (1 without a rectification rotation).
    z_factor: Vec<f64>,
    /// `p`'s pinhole: the rectified image's intrinsics.
    intrinsics: Intrinsics,
}

/// The distortion models read: OpenCV's, `d = [k1, k2, p1, p2, k3, k4, k5, k6]` (fewer is
/// zeros after).
const MODELS: [&str; 2] = ["plumb_bob", "rational_polynomial"];

impl Rectifier {
    /// The remapping of `info`'s raw image into `p`'s pinhole (`k` when `p` is not filled in).
    ///
    /// # Errors
    ///
    /// [`InputError::Distortion`] for a model other than `plumb_bob` and
    /// `rational_polynomial` (with coefficients not all zero), or more than eight
    /// coefficients; [`InputError::Intrinsics`] for a `k` or `p` that is no pinhole.
    pub fn new(info: &CameraInfo) -> Result<Self, InputError> {
        let d = &info.d;
        let distorts = crate::convert::lists_distortion(info);
        if distorts && !MODELS.contains(&info.distortion_model.as_str()) || d.len() > 8 {
            return Err(InputError::Distortion {
                model: info.distortion_model.clone(),
                coefficients: d.len(),
            });
        }
        let c = |i: usize| d.get(i).copied().unwrap_or(0.0);
        let (k1, k2, p1, p2, k3, k4, k5, k6) = (c(0), c(1), c(2), c(3), c(4), c(5), c(6), c(7));
        let k = &info.k;
        let raw = Intrinsics::new(k[0], k[4], k[2], k[5]).map_err(InputError::Intrinsics)?;
        let (w, h) = (info.width as usize, info.height as usize);
        let rect = crate::convert::pinhole(info).map_err(InputError::Intrinsics)?;
        let r = if info.r.iter().all(|&v| v == 0.0) {
            Matrix3::identity()
        } else {
            Matrix3::from_row_slice(&info.r)
        };
        let r_inv = r.transpose();
        let mut source = Vec::with_capacity(w * h);
        let mut z_factor = Vec::with_capacity(w * h);
        for v in 0..h {
            for u in 0..w {
                let ray = nalgebra::Vector3::new(
                    (u as f64 - rect.cx_px) / rect.fx_px,
                    (v as f64 - rect.cy_px) / rect.fy_px,
                    1.0,
                );
                let q = r_inv * ray;
                let (x, y) = (q.x / q.z, q.y / q.z);
                let r2 = x * x + y * y;
                let radial = (1.0 + r2 * (k1 + r2 * (k2 + r2 * k3)))
                    / (1.0 + r2 * (k4 + r2 * (k5 + r2 * k6)));
                let xd = x * radial + 2.0 * p1 * x * y + p2 * (r2 + 2.0 * x * x);
                let yd = y * radial + p1 * (r2 + 2.0 * y * y) + 2.0 * p2 * x * y;
                let (ur, vr) = (
                    (raw.fx_px * xd + raw.cx_px).round(),
                    (raw.fy_px * yd + raw.cy_px).round(),
                );
                let inside =
                    q.z > 0.0 && (0.0..w as f64).contains(&ur) && (0.0..h as f64).contains(&vr);
                source.push(if inside {
                    (vr as usize * w + ur as usize) as u32
                } else {
                    u32::MAX
                });
                z_factor.push(1.0 / q.z);
            }
        }
        Ok(Self {
            info: info.clone(),
            source,
            z_factor,
            intrinsics: rect,
        })
    }

    /// True when it was made for a camera_info with these calibration fields and size.
    pub fn fits(&self, info: &CameraInfo) -> bool {
        let a = &self.info;
        (a.width, a.height, &a.distortion_model, &a.d, a.k, a.r, a.p)
            == (
                info.width,
                info.height,
                &info.distortion_model,
                &info.d,
                info.k,
                info.r,
                info.p,
            )
    }

    /// The rectified image's intrinsics (`p`'s).
    pub fn intrinsics(&self) -> Intrinsics {
        self.intrinsics
    }

    /// The depth (metres, the raw camera's z; 0 or NaN: none) remapped: the rectified camera's
    /// z, 0 where the ray leaves the raw image.
    pub fn depth(&self, raw: &Grid<f64>) -> Grid<f64> {
        let (w, h) = (self.info.width as usize, self.info.height as usize);
        let data = raw.as_slice();
        let out = self
            .source
            .iter()
            .zip(&self.z_factor)
            .map(|(&s, &f)| match data.get(s as usize) {
                Some(&z) if z.is_finite() && z > 0.0 => z * f,
                _ => 0.0,
            })
            .collect();
        Grid::from_vec(w, h, out).expect("one value per pixel")
    }

    /// The colour image remapped (black where the ray leaves the raw image).
    pub fn rgb(&self, raw: &RgbImage) -> RgbImage {
        let pixels = raw.as_raw();
        let mut out = Vec::with_capacity(self.source.len() * 3);
        for &s in &self.source {
            let i = s as usize * 3;
            out.extend_from_slice(pixels.get(i..i + 3).unwrap_or(&[0, 0, 0]));
        }
        RgbImage::from_raw(self.info.width, self.info.height, out).expect("three bytes a pixel")
    }
}

#[cfg(test)]
mod tests_support {
    use super::*;

    const D: [f64; 5] = [-0.3, 0.1, 0.001, -0.001, 0.0];

    pub(super) fn info() -> CameraInfo {
        CameraInfo {
            width: 160,
            height: 120,
            distortion_model: "plumb_bob".into(),
            d: D.to_vec(),
            k: [120.0, 0.0, 80.0, 0.0, 120.0, 60.0, 0.0, 0.0, 1.0],
            p: [
                100.0, 0.0, 79.0, 0.0, 0.0, 101.0, 61.0, 0.0, 0.0, 0.0, 1.0, 0.0,
            ],
            ..CameraInfo::default()
        }
    }

    /// The undistorted normalised coordinates of a distorted raw pixel (OpenCV's iteration).
    fn undistorted(xd: f64, yd: f64) -> (f64, f64) {
        let [k1, k2, p1, p2, k3] = D;
        let (mut x, mut y) = (xd, yd);
        for _ in 0..50 {
            let r2 = x * x + y * y;
            let radial = 1.0 + r2 * (k1 + r2 * (k2 + r2 * k3));
            let dx = 2.0 * p1 * x * y + p2 * (r2 + 2.0 * x * x);
            let dy = p1 * (r2 + 2.0 * y * y) + 2.0 * p2 * x * y;
            (x, y) = ((xd - dx) / radial, (yd - dy) / radial);
        }
        (x, y)
    }

    /// The plane z = 2 + 0.5·x seen along the normalised ray (x, y, 1): its z.
    fn plane_z(x: f64) -> f64 {
        2.0 / (1.0 - 0.5 * x)
    }

    /// The raw image a lens with distortion `D` gives of the plane (`info()`'s `k`).
    pub(super) fn distorted_plane() -> Grid<f64> {
        Grid::from_fn(160, 120, |u, v| {
            let (x, _) = undistorted((u as f64 - 80.0) / 120.0, (v as f64 - 60.0) / 120.0);
            plane_z(x)
        })
    }
}

#[cfg(test)]
mod tests {
    use super::tests_support::{distorted_plane, info};
    use super::*;

    /// The largest distance from the plane of a depth read through a pinhole, and how many
    /// pixels had depth.
    fn off_plane(depth: &Grid<f64>, k: &Intrinsics) -> (f64, usize) {
        let (w, h) = depth.size();
        let mut worst: f64 = 0.0;
        let mut n = 0;
        for v in 0..h {
            for u in 0..w {
                let z = depth[(u, v)];
                if z > 0.0 {
                    let x = (u as f64 - k.cx_px) / k.fx_px * z;
                    worst = worst.max((z - (2.0 + 0.5 * x)).abs());
                    n += 1;
                }
            }
        }
        (worst, n)
    }

    #[test]
    fn a_distorted_plane_is_flat_again() {
        let info = info();
        let raw = distorted_plane();
        let naive = Intrinsics::new(120.0, 120.0, 80.0, 60.0).unwrap();
        let (read_raw, _) = off_plane(&raw, &naive);
        let r = Rectifier::new(&info).unwrap();
        assert_eq!((r.intrinsics().fx_px, r.intrinsics().cy_px), (100.0, 61.0));
        let (rectified, n) = off_plane(&r.depth(&raw), &r.intrinsics());
        // Read through k as if rectified, the plane bends by decimetres at the edges (31 cm);
        // remapped, what remains is the nearest raw pixel's offset of up to half a pixel (1.2 cm
        // where the plane is steepest).
        assert!(read_raw > 0.2, "raw read as rectified: {read_raw} m off");
        assert!(
            rectified < 0.02,
            "rectified: {rectified} m off, raw {read_raw}"
        );
        assert!(n > 160 * 120 * 9 / 10, "{n} pixels with depth");
    }

    #[test]
    fn colour_follows_and_the_calibration_is_checked() {
        let info = info();
        let r = Rectifier::new(&info).unwrap();
        let raw = RgbImage::from_fn(160, 120, |u, v| image::Rgb([u as u8, v as u8, 7]));
        let rgb = r.rgb(&raw);
        // The principal point reads the raw principal point's neighbourhood.
        let centre = rgb.get_pixel(79, 61);
        assert!((i32::from(centre[0]) - 80).abs() <= 1 && (i32::from(centre[1]) - 60).abs() <= 1);
        assert!(r.fits(&info));
        let other = CameraInfo {
            d: vec![-0.2, 0.0, 0.0, 0.0, 0.0],
            ..info.clone()
        };
        assert!(!r.fits(&other));
        let fisheye = CameraInfo {
            distortion_model: "equidistant".into(),
            d: vec![0.1, 0.0, 0.0, 0.0],
            ..info
        };
        let e = Rectifier::new(&fisheye).unwrap_err();
        assert!(e.to_string().contains("\"equidistant\""), "{e}");
    }
}

#[cfg(test)]
mod processor_tests {
    use super::*;
    use tre_pipeline::{Mode, Pipeline, PipelineConfig};
    use tre_record::msgs::Header;

    use super::tests_support::{distorted_plane, info};
    use crate::{FrameMsgs, InputError, Processor};

    fn frame(info: CameraInfo) -> FrameMsgs {
        FrameMsgs {
            depth: Some(tre_record::encode::float_image(
                &Header::default(),
                &distorted_plane(),
            )),
            colour: None,
            info: Some(info),
            pose: None,
        }
    }

    #[test]
    fn the_node_remaps_with_undistort_and_refuses_what_it_cannot_model() {
        let cfg = PipelineConfig {
            mode: Mode::Geometric,
            ..PipelineConfig::default()
        };
        let mut node = Processor::new(Pipeline::new(None), cfg, None, None).with_undistort(true);
        let out = node.process(&frame(info())).unwrap();
        assert_eq!((out.roughness.width, out.roughness.height), (160, 120));
        let fisheye = CameraInfo {
            distortion_model: "equidistant".into(),
            ..info()
        };
        let e = node.process(&frame(fisheye)).unwrap_err();
        assert!(matches!(e, InputError::Distortion { .. }), "{e}");
        // Without --undistort the same frame is read as rectified (and warned of).
        let mut plain = Processor::new(Pipeline::new(None), cfg, None, None);
        let fisheye = CameraInfo {
            distortion_model: "equidistant".into(),
            ..info()
        };
        assert!(plain.process(&frame(fisheye)).is_ok());
    }
}
