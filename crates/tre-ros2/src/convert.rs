//! Topic messages to the pipeline's inputs: depth per REP 118, colour, the intrinsics of
//! `CameraInfo`, poses (the outputs to messages: `tre_record::encode`).

use image::RgbImage;
use nalgebra::{Matrix3, Quaternion as NaQuaternion, UnitQuaternion};
use tre_core::geometry::{GeometryError, Grid, Intrinsics, Vec3};
use tre_core::map::Pose as MapPose;

use crate::error::InputError;
use tre_record::msgs::{CameraInfo, Image, Pose};

/// Bytes per row an image of `width` pixels of `bytes_per_pixel` needs, checked against the
/// message's `step`, `height` and data length.
fn checked_rows(img: &Image, bytes_per_pixel: usize) -> Result<usize, InputError> {
    let (w, h) = (img.width as usize, img.height as usize);
    let step = img.step as usize;
    if w == 0 || h == 0 {
        return Err(InputError::Empty);
    }
    if step < w * bytes_per_pixel || img.data.len() < step * h {
        return Err(InputError::ShortData {
            step: img.step,
            width: img.width,
            height: img.height,
            bytes: img.data.len(),
        });
    }
    Ok(step)
}

/// Depth in metres from a `16UC1` (millimetres, 0 = no data) or `32FC1` (metres, NaN or 0 = no
/// data) image, either byte order. The conversion of `16UC1` is the one of a 16-bit PNG at
/// 1000 units per metre (`tre infer --depth`), so both give the same bits.
pub fn depth_m(img: &Image) -> Result<Grid<f64>, InputError> {
    let (w, h) = (img.width as usize, img.height as usize);
    let big = img.is_bigendian != 0;
    let data: Vec<f64> = match img.encoding.as_str() {
        "16UC1" | "mono16" => {
            let step = checked_rows(img, 2)?;
            let mut out = Vec::with_capacity(w * h);
            for row in img.data.chunks_exact(step).take(h) {
                out.extend(row[..2 * w].chunks_exact(2).map(|b| {
                    let v = if big {
                        u16::from_be_bytes([b[0], b[1]])
                    } else {
                        u16::from_le_bytes([b[0], b[1]])
                    };
                    f64::from(v) / 1000.0
                }));
            }
            out
        }
        "32FC1" => {
            let step = checked_rows(img, 4)?;
            let mut out = Vec::with_capacity(w * h);
            for row in img.data.chunks_exact(step).take(h) {
                out.extend(row[..4 * w].chunks_exact(4).map(|b| {
                    let b = [b[0], b[1], b[2], b[3]];
                    let v = if big {
                        f32::from_be_bytes(b)
                    } else {
                        f32::from_le_bytes(b)
                    };
                    f64::from(v)
                }));
            }
            out
        }
        other => {
            return Err(InputError::Encoding {
                topic: "depth",
                encoding: other.to_owned(),
                expected: "16UC1 (millimetres) or 32FC1 (metres)",
            })
        }
    };
    let depth = Grid::from_vec(w, h, data).expect("sizes checked above");
    tre_io::check_depth(&depth).map_err(InputError::Depth)?;
    Ok(depth)
}

/// 8-bit RGB from an `rgb8` or `bgr8` image.
pub fn rgb(img: &Image) -> Result<RgbImage, InputError> {
    let swap = match img.encoding.as_str() {
        "rgb8" => false,
        "bgr8" => true,
        other => {
            return Err(InputError::Encoding {
                topic: "colour",
                encoding: other.to_owned(),
                expected: "rgb8 or bgr8",
            })
        }
    };
    let step = checked_rows(img, 3)?;
    let (w, h) = (img.width as usize, img.height as usize);
    let mut raw = Vec::with_capacity(3 * w * h);
    for row in img.data.chunks_exact(step).take(h) {
        for p in row[..3 * w].chunks_exact(3) {
            if swap {
                raw.extend([p[2], p[1], p[0]]);
            } else {
                raw.extend([p[0], p[1], p[2]]);
            }
        }
    }
    Ok(RgbImage::from_raw(img.width, img.height, raw).expect("sizes checked above"))
}

/// The pinhole of a `CameraInfo`, checked against the image it comes with ([`pinhole`]).
pub fn intrinsics(info: &CameraInfo, image: &Image) -> Result<Intrinsics, InputError> {
    if (info.width, info.height) != (image.width, image.height) {
        return Err(InputError::SizeMismatch {
            info: (info.width, info.height),
            image: (image.width, image.height),
        });
    }
    let intr = pinhole(info).map_err(InputError::Intrinsics)?;
    intr.check_for(image.width as usize, image.height as usize)
        .map_err(InputError::Intrinsics)?;
    Ok(intr)
}

/// A `CameraInfo`'s pinhole: its projection `p`, the rectified image's intrinsics (as
/// depth_image_proc reads a depth image; `k` is the raw, distorted image's), or `k` when `p` is
/// not filled in (its focal lengths zero).
pub fn pinhole(info: &CameraInfo) -> Result<Intrinsics, GeometryError> {
    let (p, k) = (&info.p, &info.k);
    let (fx, fy, cx, cy) = if p[0] != 0.0 && p[5] != 0.0 {
        (p[0], p[5], p[2], p[6])
    } else {
        (k[0], k[4], k[2], k[5])
    };
    Intrinsics::new(fx, fy, cx, cy)
}

/// True when a `CameraInfo` lists lens distortion (a coefficient of `d` not zero): its image is
/// read as rectified ([`intrinsics`]), which holds for an `image_rect` topic and not for a raw
/// one, unless the node remaps it (`--undistort`, [`crate::rectify`]).
pub fn lists_distortion(info: &CameraInfo) -> bool {
    info.d.iter().any(|&c| c != 0.0)
}

/// A `geometry_msgs/Pose` as the map's camera-to-world pose, after `camera_in_body` (the
/// camera's optical frame in the frame the pose places; identity when the pose is the camera's).
pub fn map_pose(pose: &Pose, camera_in_body: &MapPose) -> Result<MapPose, InputError> {
    let q = &pose.orientation;
    let norm = (q.x * q.x + q.y * q.y + q.z * q.z + q.w * q.w).sqrt();
    if !(norm.is_finite() && (norm - 1.0).abs() < 1e-3) {
        return Err(InputError::Pose { norm });
    }
    let rot: Matrix3<f64> = *UnitQuaternion::from_quaternion(NaQuaternion::new(q.w, q.x, q.y, q.z))
        .to_rotation_matrix()
        .matrix();
    let p = &pose.position;
    let t = Vec3::new(p.x, p.y, p.z);
    if !t.iter().all(|v| v.is_finite()) {
        return Err(InputError::Pose { norm });
    }
    Ok(MapPose {
        rotation: rot * camera_in_body.rotation,
        translation: rot * camera_in_body.translation + t,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use tre_record::msgs::{Point, Quaternion};

    fn depth_image(encoding: &str, w: u32, h: u32, bytes_per: u32, data: Vec<u8>) -> Image {
        Image {
            encoding: encoding.into(),
            width: w,
            height: h,
            step: w * bytes_per,
            data,
            ..Image::default()
        }
    }

    #[test]
    fn millimetres_and_metres_give_the_same_depth() {
        let mm: Vec<u16> = vec![1500, 0, 2250, 1000];
        let le: Vec<u8> = mm.iter().flat_map(|v| v.to_le_bytes()).collect();
        let be: Vec<u8> = mm.iter().flat_map(|v| v.to_be_bytes()).collect();
        let a = depth_m(&depth_image("16UC1", 2, 2, 2, le)).unwrap();
        let mut big = depth_image("16UC1", 2, 2, 2, be);
        big.is_bigendian = 1;
        let b = depth_m(&big).unwrap();
        assert_eq!(a, b);
        assert_eq!(a.as_slice(), &[1.5, 0.0, 2.25, 1.0]);
        let m: Vec<u8> = [1.5f32, f32::NAN, 2.25, 1.0]
            .iter()
            .flat_map(|v| v.to_le_bytes())
            .collect();
        let c = depth_m(&depth_image("32FC1", 2, 2, 4, m)).unwrap();
        assert_eq!(c.as_slice()[0], 1.5);
        assert!(c.as_slice()[1].is_nan());
    }

    #[test]
    fn bad_images_are_refused_with_the_reason() {
        let e = depth_m(&depth_image("8UC3", 2, 2, 3, vec![0; 12])).unwrap_err();
        assert!(e.to_string().contains("8UC3"), "{e}");
        let e = depth_m(&depth_image("16UC1", 4, 4, 2, vec![0; 10])).unwrap_err();
        assert!(matches!(e, InputError::ShortData { .. }), "{e}");
        let e = depth_m(&depth_image("16UC1", 2, 2, 2, vec![0; 8])).unwrap_err();
        assert!(e.to_string().contains("no valid pixel"), "{e}");
        let info = CameraInfo {
            width: 640,
            height: 480,
            k: [500.0, 0.0, 320.0, 0.0, 500.0, 240.0, 0.0, 0.0, 1.0],
            ..CameraInfo::default()
        };
        let img = depth_image("16UC1", 320, 240, 2, vec![0; 320 * 240 * 2]);
        let e = intrinsics(&info, &img).unwrap_err();
        assert!(e.to_string().contains("640×480"), "{e}");
    }

    #[test]
    fn the_intrinsics_are_the_rectified_images() {
        let img = depth_image("16UC1", 640, 480, 2, vec![0; 640 * 480 * 2]);
        // An Azure Kinect-like camera_info: a distorted raw image's k, the rectified p.
        let mut info = CameraInfo {
            width: 640,
            height: 480,
            distortion_model: "rational_polynomial".into(),
            d: vec![0.5, -2.6, 0.0, 0.0, 1.4, 0.4, -2.4, 1.3],
            k: [504.0, 0.0, 322.0, 0.0, 504.0, 334.0, 0.0, 0.0, 1.0],
            p: [
                480.0, 0.0, 318.0, 0.0, 0.0, 481.0, 330.0, 0.0, 0.0, 0.0, 1.0, 0.0,
            ],
            ..CameraInfo::default()
        };
        let k = intrinsics(&info, &img).unwrap();
        assert_eq!(
            (k.fx_px, k.fy_px, k.cx_px, k.cy_px),
            (480.0, 481.0, 318.0, 330.0)
        );
        assert!(lists_distortion(&info));
        // A camera_info without p (all zero, or only its homogeneous 1): k.
        info.p = [0.0; 12];
        info.p[10] = 1.0;
        info.d = vec![0.0; 5];
        let k = intrinsics(&info, &img).unwrap();
        assert_eq!((k.fx_px, k.cx_px, k.cy_px), (504.0, 322.0, 334.0));
        assert!(!lists_distortion(&info));
        info.d.clear();
        assert!(!lists_distortion(&info));
    }

    #[test]
    fn bgr_is_swapped_to_rgb() {
        let img = depth_image("bgr8", 1, 1, 3, vec![1, 2, 3]);
        assert_eq!(rgb(&img).unwrap().into_raw(), vec![3, 2, 1]);
    }

    #[test]
    fn a_pose_places_the_camera_after_its_mounting() {
        let quarter = std::f64::consts::FRAC_1_SQRT_2;
        let pose = Pose {
            position: Point {
                x: 1.0,
                y: 2.0,
                z: 0.5,
            },
            // 90° about z.
            orientation: Quaternion {
                x: 0.0,
                y: 0.0,
                z: quarter,
                w: quarter,
            },
        };
        let mount = MapPose {
            rotation: Matrix3::identity(),
            translation: Vec3::new(0.2, 0.0, 0.0),
        };
        let p = map_pose(&pose, &mount).unwrap();
        assert!((p.translation - Vec3::new(1.0, 2.2, 0.5)).norm() < 1e-12);
        let bad = Pose {
            orientation: Quaternion {
                w: 2.0,
                ..Quaternion::default()
            },
            ..pose
        };
        assert!(map_pose(&bad, &mount).is_err());
    }
}
