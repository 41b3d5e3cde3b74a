//! The `.msg` definitions of the message types, each with the definitions of the types it
//! uses, and their [`RosMessage`] names.

use super::{
    CameraInfo, CompressedImage, GridMap, Image, OccupancyGrid, Odometry, PoseStamped, RosMessage,
};

const TIME: (&str, &str) = ("builtin_interfaces/Time", "int32 sec\nuint32 nanosec\n");
const HEADER: (&str, &str) = (
    "std_msgs/Header",
    "builtin_interfaces/Time stamp\nstring frame_id\n",
);
const POINT: (&str, &str) = ("geometry_msgs/Point", "float64 x\nfloat64 y\nfloat64 z\n");
const QUATERNION: (&str, &str) = (
    "geometry_msgs/Quaternion",
    "float64 x 0\nfloat64 y 0\nfloat64 z 0\nfloat64 w 1\n",
);
const POSE: (&str, &str) = (
    "geometry_msgs/Pose",
    "geometry_msgs/Point position\ngeometry_msgs/Quaternion orientation\n",
);
const VECTOR3: (&str, &str) = ("geometry_msgs/Vector3", "float64 x\nfloat64 y\nfloat64 z\n");
const TWIST: (&str, &str) = (
    "geometry_msgs/Twist",
    "geometry_msgs/Vector3 linear\ngeometry_msgs/Vector3 angular\n",
);
const POSE_COV: (&str, &str) = (
    "geometry_msgs/PoseWithCovariance",
    "geometry_msgs/Pose pose\nfloat64[36] covariance\n",
);
const TWIST_COV: (&str, &str) = (
    "geometry_msgs/TwistWithCovariance",
    "geometry_msgs/Twist twist\nfloat64[36] covariance\n",
);
const ROI: (&str, &str) = (
    "sensor_msgs/RegionOfInterest",
    "uint32 x_offset\nuint32 y_offset\nuint32 height\nuint32 width\nbool do_rectify\n",
);
const MAP_META: (&str, &str) = (
    "nav_msgs/MapMetaData",
    "builtin_interfaces/Time map_load_time\nfloat32 resolution\nuint32 width\nuint32 height\n\
     geometry_msgs/Pose origin\n",
);
const DIM: (&str, &str) = (
    "std_msgs/MultiArrayDimension",
    "string label\nuint32 size\nuint32 stride\n",
);
const LAYOUT: (&str, &str) = (
    "std_msgs/MultiArrayLayout",
    "std_msgs/MultiArrayDimension[] dim\nuint32 data_offset\n",
);
const F32_ARRAY: (&str, &str) = (
    "std_msgs/Float32MultiArray",
    "std_msgs/MultiArrayLayout layout\nfloat32[] data\n",
);
const GRID_MAP_INFO: (&str, &str) = (
    "grid_map_msgs/GridMapInfo",
    "float64 resolution\nfloat64 length_x\nfloat64 length_y\ngeometry_msgs/Pose pose\n",
);

/// The main text, then one `MSG:` section per dependency, separated as `ros2 bag` writes them.
fn with_deps(main: &str, deps: &[(&str, &str)]) -> String {
    let mut s = main.to_owned();
    for (name, text) in deps {
        s.push_str(
            "================================================================================\n",
        );
        s.push_str(&format!("MSG: {name}\n{text}"));
    }
    s
}

impl RosMessage for Image {
    const PACKAGE: &'static str = "sensor_msgs";
    const NAME: &'static str = "Image";
    fn definition() -> String {
        with_deps(
            "std_msgs/Header header\nuint32 height\nuint32 width\nstring encoding\n\
             uint8 is_bigendian\nuint32 step\nuint8[] data\n",
            &[HEADER, TIME],
        )
    }
}

impl RosMessage for CompressedImage {
    const PACKAGE: &'static str = "sensor_msgs";
    const NAME: &'static str = "CompressedImage";
    fn definition() -> String {
        with_deps(
            "std_msgs/Header header\nstring format\nuint8[] data\n",
            &[HEADER, TIME],
        )
    }
}

impl RosMessage for CameraInfo {
    const PACKAGE: &'static str = "sensor_msgs";
    const NAME: &'static str = "CameraInfo";
    fn definition() -> String {
        with_deps(
            "std_msgs/Header header\nuint32 height\nuint32 width\nstring distortion_model\n\
             float64[] d\nfloat64[9] k\nfloat64[9] r\nfloat64[12] p\nuint32 binning_x\n\
             uint32 binning_y\nsensor_msgs/RegionOfInterest roi\n",
            &[HEADER, TIME, ROI],
        )
    }
}

impl RosMessage for PoseStamped {
    const PACKAGE: &'static str = "geometry_msgs";
    const NAME: &'static str = "PoseStamped";
    fn definition() -> String {
        with_deps(
            "std_msgs/Header header\ngeometry_msgs/Pose pose\n",
            &[HEADER, TIME, POSE, POINT, QUATERNION],
        )
    }
}

impl RosMessage for Odometry {
    const PACKAGE: &'static str = "nav_msgs";
    const NAME: &'static str = "Odometry";
    fn definition() -> String {
        with_deps(
            "std_msgs/Header header\nstring child_frame_id\n\
             geometry_msgs/PoseWithCovariance pose\ngeometry_msgs/TwistWithCovariance twist\n",
            &[
                HEADER, TIME, POSE_COV, POSE, POINT, QUATERNION, TWIST_COV, TWIST, VECTOR3,
            ],
        )
    }
}

impl RosMessage for OccupancyGrid {
    const PACKAGE: &'static str = "nav_msgs";
    const NAME: &'static str = "OccupancyGrid";
    fn definition() -> String {
        with_deps(
            "std_msgs/Header header\nnav_msgs/MapMetaData info\nint8[] data\n",
            &[HEADER, TIME, MAP_META, POSE, POINT, QUATERNION],
        )
    }
}

impl RosMessage for GridMap {
    const PACKAGE: &'static str = "grid_map_msgs";
    const NAME: &'static str = "GridMap";
    fn definition() -> String {
        with_deps(
            "std_msgs/Header header\ngrid_map_msgs/GridMapInfo info\nstring[] layers\n\
             string[] basic_layers\nstd_msgs/Float32MultiArray[] data\n\
             uint16 outer_start_index\nuint16 inner_start_index\n",
            &[
                HEADER,
                TIME,
                GRID_MAP_INFO,
                POSE,
                POINT,
                QUATERNION,
                F32_ARRAY,
                LAYOUT,
                DIM,
            ],
        )
    }
}
