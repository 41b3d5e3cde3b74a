//! The kitchen sequence (`../shared/data/real-rgbd-2/sevenscenes_redkitchen`) as ROS 2
//! messages: its depth frames, camera_info and poses, stamped by frame.

use std::path::{Path, PathBuf};

use nalgebra::{Matrix3, Rotation3, UnitQuaternion};
use tre::record::msgs::{
    CameraInfo, Header, Image, Odometry, Point, Pose, PoseWithCovariance, Quaternion, Time,
};

use crate::common::shared_data;

pub(super) struct Kitchen {
    pub(super) dir: PathBuf,
    pub(super) stems: Vec<String>,
    pub(super) camera: PathBuf,
    pub(super) gravity: [f64; 3],
}

pub(super) fn kitchen(n: usize) -> Option<Kitchen> {
    let dir = shared_data("data/real-rgbd-2/sevenscenes_redkitchen")?;
    let g: serde_json::Value =
        serde_json::from_slice(&std::fs::read(dir.join("gravity.json")).unwrap()).unwrap();
    let gravity = [0, 1, 2].map(|i| g["gravity"][i].as_f64().unwrap());
    Some(Kitchen {
        stems: (0..n).map(|i| format!("frame-{:06}", 5 * i)).collect(),
        dir,
        camera: Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("cameras/real-rgbd-2_sevenscenes_redkitchen.json"),
        gravity,
    })
}

pub(super) fn stamp(i: usize) -> Time {
    Time {
        sec: 1_700_000_000 + i as i32,
        nanosec: 0,
    }
}

pub(super) fn header(i: usize) -> Header {
    Header {
        stamp: stamp(i),
        frame_id: "camera_depth_optical_frame".into(),
    }
}

pub(super) fn depth_msg(path: &Path, i: usize) -> Image {
    tre::record::encode::depth_mm_image(&header(i), &image::open(path).unwrap().to_luma16())
}

pub(super) fn info_msg(i: usize, (w, h): (u32, u32)) -> CameraInfo {
    CameraInfo {
        header: header(i),
        width: w,
        height: h,
        distortion_model: "plumb_bob".into(),
        d: vec![0.0; 5],
        k: [585.0, 0.0, 320.0, 0.0, 585.0, 240.0, 0.0, 0.0, 1.0],
        r: [1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0],
        p: [
            585.0, 0.0, 320.0, 0.0, 0.0, 585.0, 240.0, 0.0, 0.0, 0.0, 1.0, 0.0,
        ],
        ..CameraInfo::default()
    }
}

/// The kitchen pose of `stem` as a ROS pose, and the same pose after the node's quaternion
/// conversion as a 4×4 text `tre map` reads (so both fuse with the same bits).
pub(super) fn pose_msg(k: &Kitchen, stem: &str) -> (Pose, String) {
    let text = std::fs::read_to_string(k.dir.join(format!("poses/{stem}.txt"))).unwrap();
    let v: Vec<f64> = text
        .split_whitespace()
        .map(|s| s.parse().unwrap())
        .collect();
    let m = Matrix3::new(v[0], v[1], v[2], v[4], v[5], v[6], v[8], v[9], v[10]);
    let q = UnitQuaternion::from_rotation_matrix(&Rotation3::from_matrix(&m));
    let pose = Pose {
        position: Point {
            x: v[3],
            y: v[7],
            z: v[11],
        },
        orientation: Quaternion {
            x: q.i,
            y: q.j,
            z: q.k,
            w: q.w,
        },
    };
    let p = tre::ros2::convert::map_pose(&pose, &tre::map::Pose::identity()).unwrap();
    let (r, t) = (p.rotation, p.translation);
    let text = format!(
        "{:?} {:?} {:?} {:?}\n{:?} {:?} {:?} {:?}\n{:?} {:?} {:?} {:?}\n0 0 0 1\n",
        r[(0, 0)],
        r[(0, 1)],
        r[(0, 2)],
        t.x,
        r[(1, 0)],
        r[(1, 1)],
        r[(1, 2)],
        t.y,
        r[(2, 0)],
        r[(2, 1)],
        r[(2, 2)],
        t.z,
    );
    (pose, text)
}

pub(super) fn odom_msg(pose: Pose, i: usize) -> Odometry {
    Odometry {
        header: Header {
            stamp: stamp(i),
            frame_id: "world".into(),
        },
        child_frame_id: "camera_depth_optical_frame".into(),
        pose: PoseWithCovariance {
            pose,
            ..PoseWithCovariance::default()
        },
        ..Odometry::default()
    }
}
