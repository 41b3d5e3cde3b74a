//! tre's data as ROS 2 messages: depth (`32FC1` metres or `16UC1` millimetres, REP 118), colour (`rgb8`), encoded
//! images as they were sent, intrinsics as `CameraInfo`, poses; roughness and uncertainty as
//! `32FC1`, the three-state map as `mono8`, the fused map as `grid_map_msgs/GridMap` and
//! `nav_msgs/OccupancyGrid`.

use image::{ImageBuffer, Luma, RgbImage};
use nalgebra::{Rotation3, UnitQuaternion};
use tre_core::geometry::{Grid, Intrinsics};
use tre_core::map::{GridMap as Map, Layers, Pose as MapPose, LAYER_NAMES};
use tre_core::roughness::traversal::Traversal;

use crate::msgs::{
    CameraInfo, CompressedImage, Float32MultiArray, GridMap, GridMapInfo, Header, Image,
    MapMetaData, MultiArrayDimension, MultiArrayLayout, OccupancyGrid, Point, Pose, PoseStamped,
    Quaternion, Time,
};

/// A stamp from microseconds since the Unix epoch.
pub fn stamp_us(us: i64) -> Time {
    Time::from_nanos(us.saturating_mul(1000))
}

/// An `rgb8` image of `rgb`.
pub fn rgb_image(header: &Header, rgb: &RgbImage) -> Image {
    Image {
        header: header.clone(),
        height: rgb.height(),
        width: rgb.width(),
        encoding: "rgb8".into(),
        is_bigendian: 0,
        step: 3 * rgb.width(),
        data: rgb.as_raw().clone(),
    }
}

/// An encoded image as it was sent: `format` is `png` or `jpeg`, told by its first bytes.
pub fn compressed_image(header: &Header, bytes: &[u8]) -> CompressedImage {
    let format = if bytes.starts_with(&[0xff, 0xd8]) {
        "jpeg"
    } else {
        "png"
    };
    CompressedImage {
        header: header.clone(),
        format: format.into(),
        data: bytes.to_vec(),
    }
}

/// The `CameraInfo` of a pinhole for a `width` × `height` image: `k`, `p` and no distortion.
pub fn camera_info(header: &Header, k: &Intrinsics, width: usize, height: usize) -> CameraInfo {
    CameraInfo {
        header: header.clone(),
        width: width as u32,
        height: height as u32,
        distortion_model: "plumb_bob".into(),
        d: vec![0.0; 5],
        k: [k.fx_px, 0.0, k.cx_px, 0.0, k.fy_px, k.cy_px, 0.0, 0.0, 1.0],
        r: [1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0],
        p: [
            k.fx_px, 0.0, k.cx_px, 0.0, 0.0, k.fy_px, k.cy_px, 0.0, 0.0, 0.0, 1.0, 0.0,
        ],
        ..CameraInfo::default()
    }
}

/// A camera-to-world pose as `geometry_msgs/PoseStamped` (`header.frame_id`: the world's).
pub fn pose_stamped(header: &Header, pose: &MapPose) -> PoseStamped {
    let q = UnitQuaternion::from_rotation_matrix(&Rotation3::from_matrix(&pose.rotation));
    let t = pose.translation;
    PoseStamped {
        header: header.clone(),
        pose: Pose {
            position: Point {
                x: t.x,
                y: t.y,
                z: t.z,
            },
            orientation: Quaternion {
                x: q.i,
                y: q.j,
                z: q.k,
                w: q.w,
            },
        },
    }
}

/// A `32FC1` image (little-endian) of `values` in metres, NaN where there is none.
pub fn float_image(header: &Header, values: &Grid<f64>) -> Image {
    let (w, h) = values.size();
    let mut data = Vec::with_capacity(4 * w * h);
    for v in values.as_slice() {
        data.extend((*v as f32).to_le_bytes());
    }
    Image {
        header: header.clone(),
        height: h as u32,
        width: w as u32,
        encoding: "32FC1".into(),
        is_bigendian: 0,
        step: 4 * w as u32,
        data,
    }
}

/// Metres as `mono16` millimetres, rounded to the nearest: 0 where there is no value, 1 for a
/// value under 0.5 mm (so that 0 stays "no data"), 65535 for one over 65.535 m.
pub fn millimetres(v: f64) -> u16 {
    if v.is_finite() {
        (v * 1000.0).round().clamp(1.0, 65535.0) as u16
    } else {
        0
    }
}

/// Depth as a camera driver sends it: `16UC1` millimetres, little-endian (REP 118).
pub fn depth_mm_image(header: &Header, mm: &ImageBuffer<Luma<u16>, Vec<u16>>) -> Image {
    let (w, h) = mm.dimensions();
    Image {
        header: header.clone(),
        height: h,
        width: w,
        encoding: "16UC1".into(),
        is_bigendian: 0,
        step: 2 * w,
        data: mm.as_raw().iter().flat_map(|v| v.to_le_bytes()).collect(),
    }
}

/// A `mono16` image (little-endian) of `values` in [`millimetres`].
pub fn mono16_mm_image(header: &Header, values: &Grid<f64>) -> Image {
    let (w, h) = values.size();
    let mut data = Vec::with_capacity(2 * w * h);
    for &v in values.as_slice() {
        data.extend(millimetres(v).to_le_bytes());
    }
    Image {
        header: header.clone(),
        height: h as u32,
        width: w as u32,
        encoding: "mono16".into(),
        is_bigendian: 0,
        step: 2 * w as u32,
        data,
    }
}

/// A `mono8` image of the three-state map: 0 unknown, 1 traversable, 2 hazard (the service's
/// 8-bit values).
pub fn traversal_image(header: &Header, t: &Grid<Traversal>) -> Image {
    let (w, h) = t.size();
    Image {
        header: header.clone(),
        height: h as u32,
        width: w as u32,
        encoding: "mono8".into(),
        is_bigendian: 0,
        step: w as u32,
        data: t.as_slice().iter().map(|&v| v as u8).collect(),
    }
}

/// The window's lower-left corner and side in the map frame, metres.
fn window(map: &Map) -> ((f64, f64), f64) {
    let cfg = map.config();
    let (ox, oy) = map.origin();
    let corner = (ox as f64 * cfg.cell_m, oy as f64 * cfg.cell_m);
    (corner, cfg.side as f64 * cfg.cell_m)
}

/// The map as grid_map publishes it: every layer of [`LAYER_NAMES`], column-major with the
/// dimension labels grid_map checks (`column_index`, then `row_index`), cell (0, 0) at the
/// window's largest x and y, no circular-buffer offset; `info.pose` the window's centre.
pub fn grid_map(header: &Header, map: &Map, layers: &Layers) -> GridMap {
    grid_map_layers(header, map, layers, &LAYER_NAMES)
}

/// One layer as grid_map stores it. Layers: row-major, column = +x from the smallest x, row 0
/// at the largest y. grid_map: (r, c) with r along -x from the largest x, c along -y from the
/// largest y, stored column-major (index c * side + r).
fn grid_map_layer(src: &[f32], side: usize) -> Float32MultiArray {
    let mut out = Vec::with_capacity(side * side);
    for c in 0..side {
        let row = &src[c * side..(c + 1) * side];
        out.extend(row.iter().rev());
    }
    Float32MultiArray {
        layout: MultiArrayLayout {
            dim: vec![
                MultiArrayDimension {
                    label: "column_index".into(),
                    size: side as u32,
                    stride: (side * side) as u32,
                },
                MultiArrayDimension {
                    label: "row_index".into(),
                    size: side as u32,
                    stride: side as u32,
                },
            ],
            data_offset: 0,
        },
        data: out,
    }
}

/// [`grid_map`] with the layers named in `names` only, in [`LAYER_NAMES`] order (a name not
/// there is left out).
pub fn grid_map_layers(header: &Header, map: &Map, layers: &Layers, names: &[&str]) -> GridMap {
    let side = map.config().side;
    let ((x0, y0), len) = window(map);
    let keep = |name: &&str| names.contains(name);
    let data = LAYER_NAMES
        .iter()
        .zip(layers.all())
        .filter(|(name, _)| keep(name))
        .map(|(_, layer)| grid_map_layer(layer.as_slice(), side))
        .collect();
    GridMap {
        header: header.clone(),
        info: GridMapInfo {
            resolution: map.config().cell_m,
            length_x: len,
            length_y: len,
            pose: Pose {
                position: Point {
                    x: x0 + len / 2.0,
                    y: y0 + len / 2.0,
                    z: 0.0,
                },
                orientation: Quaternion::default(),
            },
        },
        layers: LAYER_NAMES
            .iter()
            .filter(|n| keep(n))
            .map(|s| (*s).to_owned())
            .collect(),
        basic_layers: if names.contains(&"elevation") {
            vec!["elevation".into()]
        } else {
            Vec::new()
        },
        data,
        outer_start_index: 0,
        inner_start_index: 0,
    }
}

/// The map's three-state layer as an occupancy grid for Nav2: unknown −1, traversable 0,
/// hazard 100; row-major from the window's lower-left corner, x along a row.
pub fn occupancy(header: &Header, map: &Map, layers: &Layers) -> OccupancyGrid {
    let side = map.config().side;
    let ((x0, y0), _) = window(map);
    let src = layers.traversal.as_slice();
    let mut data = Vec::with_capacity(side * side);
    for iy in 0..side {
        let row = &src[(side - 1 - iy) * side..(side - iy) * side];
        data.extend(row.iter().map(|&v| match v as u8 {
            1 => 0i8,
            2 => 100,
            _ => -1,
        }));
    }
    OccupancyGrid {
        header: header.clone(),
        info: MapMetaData {
            map_load_time: header.stamp,
            resolution: map.config().cell_m as f32,
            width: side as u32,
            height: side as u32,
            origin: Pose {
                position: Point {
                    x: x0,
                    y: y0,
                    z: 0.0,
                },
                orientation: Quaternion::default(),
            },
        },
        data,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::Matrix3;
    use tre_core::geometry::Vec3;

    #[test]
    fn a_pose_and_its_quaternion_agree() {
        let rot = *Rotation3::from_axis_angle(&nalgebra::Vector3::z_axis(), 0.5).matrix();
        let pose = MapPose {
            rotation: rot,
            translation: Vec3::new(1.0, -2.0, 0.25),
        };
        let msg = pose_stamped(&Header::default(), &pose);
        let o = &msg.pose.orientation;
        assert!((o.z - 0.25f64.sin()).abs() < 1e-12 && (o.w - 0.25f64.cos()).abs() < 1e-12);
        assert_eq!(msg.pose.position.y, -2.0);
        let identity = pose_stamped(
            &Header::default(),
            &MapPose {
                rotation: Matrix3::identity(),
                translation: Vec3::zeros(),
            },
        );
        assert_eq!(identity.pose.orientation.w, 1.0);
    }

    #[test]
    fn mono16_is_rounded_millimetres_with_zero_for_no_data() {
        let g = Grid::from_vec(5, 1, vec![0.0123, f64::NAN, 0.0001, 70.0, 0.0015]).unwrap();
        let img = mono16_mm_image(&Header::default(), &g);
        assert_eq!(
            (img.encoding.as_str(), img.step, img.data.len()),
            ("mono16", 10, 10)
        );
        let mm: Vec<u16> = img
            .data
            .chunks_exact(2)
            .map(|b| u16::from_le_bytes([b[0], b[1]]))
            .collect();
        assert_eq!(mm, [12, 0, 1, 65535, 2]);
    }

    #[test]
    fn floats_are_little_endian_metres_and_png_and_jpeg_are_told_apart() {
        let g = Grid::from_vec(2, 1, vec![0.5, f64::NAN]).unwrap();
        let img = float_image(&Header::default(), &g);
        assert_eq!((img.width, img.height, img.step), (2, 1, 8));
        assert_eq!(img.data[..4], 0.5f32.to_le_bytes());
        assert!(f32::from_le_bytes(img.data[4..].try_into().unwrap()).is_nan());
        let h = Header::default();
        assert_eq!(compressed_image(&h, &[0xff, 0xd8, 0xff]).format, "jpeg");
        assert_eq!(compressed_image(&h, b"\x89PNG").format, "png");
        let k = Intrinsics::new(500.0, 510.0, 320.0, 240.0).unwrap();
        let info = camera_info(&h, &k, 640, 480);
        assert_eq!(
            (info.k[0], info.k[4], info.k[2], info.k[5]),
            (500.0, 510.0, 320.0, 240.0)
        );
    }
}
