//! The ROS 2 messages tre reads and writes, as serde types in CDR field order, each with
//! its ROS type name and its `.msg` definition (dependencies included, in the `ros2msg` form
//! that MCAP readers and `ros2 bag` take).
//!
//! Field names and order follow the message definitions of ROS 2 Humble and Jazzy (the same
//! for every type here); fixed-size arrays (`float64[9]`) are tuples on the wire, unbounded
//! ones (`uint8[]`) a length and the elements.

use serde::de::{self, SeqAccess, Visitor};
use serde::{Deserialize, Deserializer, Serialize, Serializer};

/// `builtin_interfaces/Time`: seconds and nanoseconds since the Unix epoch.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, PartialOrd, Ord, Serialize, Deserialize)]
pub struct Time {
    /// Seconds.
    pub sec: i32,
    /// Nanoseconds, below 1e9.
    pub nanosec: u32,
}

impl Time {
    /// Nanoseconds since the epoch.
    pub fn nanos(&self) -> i64 {
        i64::from(self.sec) * 1_000_000_000 + i64::from(self.nanosec)
    }

    /// The time `nanos` nanoseconds after the epoch.
    pub fn from_nanos(nanos: i64) -> Self {
        Self {
            sec: nanos.div_euclid(1_000_000_000) as i32,
            nanosec: nanos.rem_euclid(1_000_000_000) as u32,
        }
    }

    /// Seconds since the epoch.
    pub fn seconds(&self) -> f64 {
        f64::from(self.sec) + f64::from(self.nanosec) * 1e-9
    }
}

/// `std_msgs/Header`.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct Header {
    /// When the data was taken.
    pub stamp: Time,
    /// The frame the data is in.
    pub frame_id: String,
}

impl Header {
    /// A header of `stamp` in frame `frame_id`.
    pub fn new(stamp: Time, frame_id: &str) -> Self {
        Self {
            stamp,
            frame_id: frame_id.to_owned(),
        }
    }
}

/// `sensor_msgs/Image`.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct Image {
    /// Stamp and optical frame.
    pub header: Header,
    /// Rows.
    pub height: u32,
    /// Columns.
    pub width: u32,
    /// Pixel encoding (REP 118 for depth: `16UC1` millimetres, `32FC1` metres).
    pub encoding: String,
    /// 1 when multi-byte pixels are big-endian.
    pub is_bigendian: u8,
    /// Bytes per row.
    pub step: u32,
    /// The pixels, `step × height` bytes.
    pub data: Vec<u8>,
}

/// `sensor_msgs/CompressedImage`: an encoded image (`png` or `jpeg`) as it was sent.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct CompressedImage {
    /// Stamp and optical frame.
    pub header: Header,
    /// The encoding: `png` or `jpeg`.
    pub format: String,
    /// The encoded bytes.
    pub data: Vec<u8>,
}

/// `sensor_msgs/RegionOfInterest`.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct RegionOfInterest {
    /// Leftmost pixel.
    pub x_offset: u32,
    /// Topmost pixel.
    pub y_offset: u32,
    /// Rows (0: the whole image).
    pub height: u32,
    /// Columns (0: the whole image).
    pub width: u32,
    /// Whether the region is rectified.
    pub do_rectify: bool,
}

/// `sensor_msgs/CameraInfo`.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct CameraInfo {
    /// Stamp and optical frame.
    pub header: Header,
    /// Rows of the images it describes.
    pub height: u32,
    /// Columns.
    pub width: u32,
    /// Distortion model name (`plumb_bob`, ...).
    pub distortion_model: String,
    /// Distortion coefficients.
    pub d: Vec<f64>,
    /// Intrinsic matrix, row-major: fx 0 cx, 0 fy cy, 0 0 1.
    pub k: [f64; 9],
    /// Rectification rotation, row-major.
    pub r: [f64; 9],
    /// Projection matrix, row-major 3×4.
    pub p: [f64; 12],
    /// Horizontal binning.
    pub binning_x: u32,
    /// Vertical binning.
    pub binning_y: u32,
    /// Region of interest.
    pub roi: RegionOfInterest,
}

/// `geometry_msgs/Point`.
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize, Deserialize)]
pub struct Point {
    /// x, metres.
    pub x: f64,
    /// y, metres.
    pub y: f64,
    /// z, metres.
    pub z: f64,
}

/// `geometry_msgs/Quaternion`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Quaternion {
    /// x.
    pub x: f64,
    /// y.
    pub y: f64,
    /// z.
    pub z: f64,
    /// w.
    pub w: f64,
}

impl Default for Quaternion {
    fn default() -> Self {
        Self {
            x: 0.0,
            y: 0.0,
            z: 0.0,
            w: 1.0,
        }
    }
}

/// `geometry_msgs/Pose`.
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize, Deserialize)]
pub struct Pose {
    /// Position.
    pub position: Point,
    /// Orientation.
    pub orientation: Quaternion,
}

/// `geometry_msgs/PoseStamped`.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct PoseStamped {
    /// Stamp and the frame the pose is in.
    pub header: Header,
    /// The pose.
    pub pose: Pose,
}

/// A row-major 6×6 covariance (`float64[36]`).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Covariance(pub [f64; 36]);

impl Default for Covariance {
    fn default() -> Self {
        Self([0.0; 36])
    }
}

impl Serialize for Covariance {
    fn serialize<S: Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        use serde::ser::SerializeTuple;
        let mut t = s.serialize_tuple(36)?;
        for v in &self.0 {
            t.serialize_element(v)?;
        }
        t.end()
    }
}

impl<'de> Deserialize<'de> for Covariance {
    fn deserialize<D: Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        struct V;
        impl<'de> Visitor<'de> for V {
            type Value = Covariance;
            fn expecting(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
                f.write_str("36 float64")
            }
            fn visit_seq<A: SeqAccess<'de>>(self, mut seq: A) -> Result<Covariance, A::Error> {
                let mut out = [0.0; 36];
                for (i, v) in out.iter_mut().enumerate() {
                    *v = seq
                        .next_element()?
                        .ok_or_else(|| de::Error::invalid_length(i, &self))?;
                }
                Ok(Covariance(out))
            }
        }
        d.deserialize_tuple(36, V)
    }
}

/// `geometry_msgs/PoseWithCovariance`.
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize, Deserialize)]
pub struct PoseWithCovariance {
    /// The pose.
    pub pose: Pose,
    /// Its covariance.
    pub covariance: Covariance,
}

/// `geometry_msgs/Vector3`.
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize, Deserialize)]
pub struct Vector3 {
    /// x.
    pub x: f64,
    /// y.
    pub y: f64,
    /// z.
    pub z: f64,
}

/// `geometry_msgs/Twist`.
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize, Deserialize)]
pub struct Twist {
    /// Linear velocity.
    pub linear: Vector3,
    /// Angular velocity.
    pub angular: Vector3,
}

/// `geometry_msgs/TwistWithCovariance`.
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize, Deserialize)]
pub struct TwistWithCovariance {
    /// The twist.
    pub twist: Twist,
    /// Its covariance.
    pub covariance: Covariance,
}

/// `nav_msgs/Odometry`.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct Odometry {
    /// Stamp and the frame of the pose (`odom`).
    pub header: Header,
    /// The frame the pose places (`base_link`).
    pub child_frame_id: String,
    /// The pose of `child_frame_id` in `header.frame_id`.
    pub pose: PoseWithCovariance,
    /// The velocity, in `child_frame_id`.
    pub twist: TwistWithCovariance,
}

/// `nav_msgs/MapMetaData`.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct MapMetaData {
    /// When the map was made.
    pub map_load_time: Time,
    /// Cell side, metres.
    pub resolution: f32,
    /// Columns.
    pub width: u32,
    /// Rows.
    pub height: u32,
    /// Pose of cell (0, 0)'s outer corner in the header's frame.
    pub origin: Pose,
}

/// `nav_msgs/OccupancyGrid`: row-major from `info.origin`, x along a row; −1 unknown, 0 free,
/// 100 occupied.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct OccupancyGrid {
    /// Stamp and map frame.
    pub header: Header,
    /// Layout.
    pub info: MapMetaData,
    /// Cells.
    pub data: Vec<i8>,
}

/// `std_msgs/MultiArrayDimension`.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct MultiArrayDimension {
    /// Name of the dimension (grid_map checks `column_index` and `row_index`).
    pub label: String,
    /// Its size.
    pub size: u32,
    /// Stride of this dimension and those inside it.
    pub stride: u32,
}

/// `std_msgs/MultiArrayLayout`.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct MultiArrayLayout {
    /// Dimensions, outermost first.
    pub dim: Vec<MultiArrayDimension>,
    /// Elements before the data starts.
    pub data_offset: u32,
}

/// `std_msgs/Float32MultiArray`.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct Float32MultiArray {
    /// Layout.
    pub layout: MultiArrayLayout,
    /// Values.
    pub data: Vec<f32>,
}

/// `grid_map_msgs/GridMapInfo` (ROS 2).
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct GridMapInfo {
    /// Cell side, metres.
    pub resolution: f64,
    /// Extent along x, metres.
    pub length_x: f64,
    /// Extent along y, metres.
    pub length_y: f64,
    /// The map's centre in the header's frame (orientation identity).
    pub pose: Pose,
}

/// `grid_map_msgs/GridMap` (ROS 2): each layer a column-major [`Float32MultiArray`] whose
/// first dimension is `column_index`; index (0, 0) at the map's largest x and y.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct GridMap {
    /// Stamp and map frame.
    pub header: Header,
    /// Size and position.
    pub info: GridMapInfo,
    /// Layer names.
    pub layers: Vec<String>,
    /// Layers whose NaN marks a cell as invalid.
    pub basic_layers: Vec<String>,
    /// One array per layer.
    pub data: Vec<Float32MultiArray>,
    /// Circular-buffer start (0: none).
    pub outer_start_index: u16,
    /// Circular-buffer start (0: none).
    pub inner_start_index: u16,
}

/// A ROS 2 message type: its name and its definition.
pub trait RosMessage: Serialize + for<'de> Deserialize<'de> {
    /// Package, e.g. `sensor_msgs`.
    const PACKAGE: &'static str;
    /// Type, e.g. `Image`.
    const NAME: &'static str;
    /// The `.msg` text of the type, then each type it uses (`MSG: pkg/Name` sections).
    fn definition() -> String;
    /// `pkg/msg/Name`, as `ros2 bag` and MCAP name it.
    fn schema_name() -> String {
        format!("{}/msg/{}", Self::PACKAGE, Self::NAME)
    }
}

mod definitions;

/// The CDR bytes of a message as ROS 2 puts them in a bag or an MCAP file: the 4-byte
/// encapsulation header (little-endian plain CDR) then the fields.
pub fn to_cdr<M: Serialize>(msg: &M) -> Result<Vec<u8>, cdr_encoding::Error> {
    let mut out = vec![0x00, 0x01, 0x00, 0x00];
    out.extend(cdr_encoding::to_vec::<M, byteorder::LittleEndian>(msg)?);
    Ok(out)
}

/// A message from CDR bytes with their encapsulation header (either byte order).
pub fn from_cdr<M: for<'de> Deserialize<'de>>(bytes: &[u8]) -> Result<M, cdr_encoding::Error> {
    let (head, body) = bytes.split_at(bytes.len().min(4));
    let msg = if head.get(1) == Some(&0x00) {
        cdr_encoding::from_bytes::<M, byteorder::BigEndian>(body)?.0
    } else {
        cdr_encoding::from_bytes::<M, byteorder::LittleEndian>(body)?.0
    };
    Ok(msg)
}

/// The types DDS topics carry (the `dds` feature): ros2-client's marker trait.
#[cfg(feature = "dds")]
macro_rules! ros2_message {
    ($($t:ty),*) => { $(impl ros2_client::Message for $t {})* };
}
#[cfg(feature = "dds")]
ros2_message!(
    Image,
    CameraInfo,
    PoseStamped,
    Odometry,
    OccupancyGrid,
    GridMap
);

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn cdr_round_trip_keeps_every_field() {
        let img = Image {
            header: Header {
                stamp: Time::from_nanos(1_700_000_000_123_456_789),
                frame_id: "camera_optical".into(),
            },
            height: 2,
            width: 3,
            encoding: "16UC1".into(),
            is_bigendian: 0,
            step: 6,
            data: (0..12).collect(),
        };
        let bytes = to_cdr(&img).unwrap();
        assert_eq!(&bytes[..4], &[0, 1, 0, 0]);
        assert_eq!(from_cdr::<Image>(&bytes).unwrap(), img);
        let odom = Odometry {
            child_frame_id: "base_link".into(),
            pose: PoseWithCovariance {
                covariance: Covariance([0.5; 36]),
                ..Default::default()
            },
            ..Default::default()
        };
        assert_eq!(from_cdr::<Odometry>(&to_cdr(&odom).unwrap()).unwrap(), odom);
    }

    #[test]
    fn definitions_name_every_dependency_once() {
        let d = GridMap::definition();
        for dep in [
            "std_msgs/Header",
            "grid_map_msgs/GridMapInfo",
            "std_msgs/MultiArrayDimension",
        ] {
            assert_eq!(d.matches(&format!("MSG: {dep}\n")).count(), 1, "{dep}");
        }
        assert_eq!(GridMap::schema_name(), "grid_map_msgs/msg/GridMap");
    }
}
