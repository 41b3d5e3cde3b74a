"""The ROS 2 peer of scripts/ros2_rates.py in Eclipse Cyclone DDS (the `cyclonedds` wheel).

The message types are ROS 2's, field by field, under their DDS names; the data representation
is XCDR1 (plain CDR), as every ROS 2 middleware writes it. Settings are Cyclone's defaults.
"""

import struct
import threading
import time
from dataclasses import dataclass, field

from cyclonedds._clayer import ddspy_write
from cyclonedds.core import Policy, Qos
from cyclonedds.domain import DomainParticipant
from cyclonedds.idl import IdlStruct
from cyclonedds.idl.types import (
    array,
    float32,
    float64,
    int8,
    int32,
    sequence,
    uint8,
    uint16,
    uint32,
)
from cyclonedds.pub import DataWriter
from cyclonedds.sub import DataReader
from cyclonedds.topic import Topic
from cyclonedds.util import duration


@dataclass
class Time(IdlStruct, typename="builtin_interfaces::msg::dds_::Time_"):
    sec: int32
    nanosec: uint32


@dataclass
class Header(IdlStruct, typename="std_msgs::msg::dds_::Header_"):
    stamp: Time
    frame_id: str


@dataclass
class Image(IdlStruct, typename="sensor_msgs::msg::dds_::Image_"):
    header: Header
    height: uint32
    width: uint32
    encoding: str
    is_bigendian: uint8
    step: uint32
    data: sequence[uint8]


@dataclass
class CompressedImage(IdlStruct, typename="sensor_msgs::msg::dds_::CompressedImage_"):
    header: Header
    format: str
    data: sequence[uint8]


@dataclass
class RegionOfInterest(IdlStruct, typename="sensor_msgs::msg::dds_::RegionOfInterest_"):
    x_offset: uint32 = 0
    y_offset: uint32 = 0
    height: uint32 = 0
    width: uint32 = 0
    do_rectify: bool = False


@dataclass
class CameraInfo(IdlStruct, typename="sensor_msgs::msg::dds_::CameraInfo_"):
    header: Header
    height: uint32
    width: uint32
    distortion_model: str
    d: sequence[float64]
    k: array[float64, 9]
    r: array[float64, 9]
    p: array[float64, 12]
    binning_x: uint32 = 0
    binning_y: uint32 = 0
    roi: RegionOfInterest = field(default_factory=RegionOfInterest)


@dataclass
class Point(IdlStruct, typename="geometry_msgs::msg::dds_::Point_"):
    x: float64
    y: float64
    z: float64


@dataclass
class Quaternion(IdlStruct, typename="geometry_msgs::msg::dds_::Quaternion_"):
    x: float64
    y: float64
    z: float64
    w: float64


@dataclass
class Pose(IdlStruct, typename="geometry_msgs::msg::dds_::Pose_"):
    position: Point
    orientation: Quaternion


@dataclass
class PoseWithCovariance(IdlStruct, typename="geometry_msgs::msg::dds_::PoseWithCovariance_"):
    pose: Pose
    covariance: array[float64, 36]


@dataclass
class Vector3(IdlStruct, typename="geometry_msgs::msg::dds_::Vector3_"):
    x: float64 = 0.0
    y: float64 = 0.0
    z: float64 = 0.0


@dataclass
class Twist(IdlStruct, typename="geometry_msgs::msg::dds_::Twist_"):
    linear: Vector3 = field(default_factory=Vector3)
    angular: Vector3 = field(default_factory=Vector3)


@dataclass
class TwistWithCovariance(IdlStruct, typename="geometry_msgs::msg::dds_::TwistWithCovariance_"):
    twist: Twist = field(default_factory=Twist)
    covariance: array[float64, 36] = field(default_factory=lambda: [0.0] * 36)


@dataclass
class Odometry(IdlStruct, typename="nav_msgs::msg::dds_::Odometry_"):
    header: Header
    child_frame_id: str
    pose: PoseWithCovariance
    twist: TwistWithCovariance = field(default_factory=TwistWithCovariance)


@dataclass
class MapMetaData(IdlStruct, typename="nav_msgs::msg::dds_::MapMetaData_"):
    map_load_time: Time
    resolution: float32
    width: uint32
    height: uint32
    origin: Pose


@dataclass
class OccupancyGrid(IdlStruct, typename="nav_msgs::msg::dds_::OccupancyGrid_"):
    header: Header
    info: MapMetaData
    data: sequence[int8]


@dataclass
class MultiArrayDimension(IdlStruct, typename="std_msgs::msg::dds_::MultiArrayDimension_"):
    label: str
    size: uint32
    stride: uint32


@dataclass
class MultiArrayLayout(IdlStruct, typename="std_msgs::msg::dds_::MultiArrayLayout_"):
    dim: sequence[MultiArrayDimension]
    data_offset: uint32


@dataclass
class Float32MultiArray(IdlStruct, typename="std_msgs::msg::dds_::Float32MultiArray_"):
    layout: MultiArrayLayout
    data: sequence[float32]


@dataclass
class GridMapInfo(IdlStruct, typename="grid_map_msgs::msg::dds_::GridMapInfo_"):
    resolution: float64
    length_x: float64
    length_y: float64
    pose: Pose


@dataclass
class GridMap(IdlStruct, typename="grid_map_msgs::msg::dds_::GridMap_"):
    header: Header
    info: GridMapInfo
    layers: sequence[str]
    basic_layers: sequence[str]
    data: sequence[Float32MultiArray]
    outer_start_index: uint16
    inner_start_index: uint16


OUTPUTS = {
    "roughness": Image,
    "roughness/compressed": CompressedImage,
    "uncertainty": Image,
    "uncertainty/compressed": CompressedImage,
    "traversal": Image,
    "traversal/compressed": CompressedImage,
    "grid_map": GridMap,
    "occupancy": OccupancyGrid,
}

XCDR1 = Policy.DataRepresentation(use_cdrv0_representation=True)


class Peer:
    """Publishes depth, camera_info and odometry; counts the node's outputs into `tally`."""

    def __init__(self, domain: int, reliable: bool, tally, topics: list[str]) -> None:
        self.dp = DomainParticipant(domain)
        self.serialised: dict[int, bytearray] = {}
        # A ROS 2 publisher's default profile: reliable, volatile, keep the last 10.
        pub_qos = Qos(
            Policy.Reliability.Reliable(duration(seconds=1)), Policy.History.KeepLast(10), XCDR1
        )
        self.depth = self._writer("rt/camera/depth/image_rect_raw", Image, pub_qos)
        self.info = self._writer("rt/camera/depth/camera_info", CameraInfo, pub_qos)
        self.odom = self._writer("rt/odom", Odometry, pub_qos)
        # The subscriber's: the default profile (reliable, keep 10) or the sensor-data one
        # (best effort, keep 5); the occupancy grid reliable and transient-local as Nav2's map
        # subscriber, keeping 10 (not Nav2's 1) so that every grid is counted.
        if reliable:
            sub = [Policy.Reliability.Reliable(duration(seconds=1)), Policy.History.KeepLast(10)]
        else:
            sub = [Policy.Reliability.BestEffort, Policy.History.KeepLast(5)]
        self.readers = []
        for name, kind in OUTPUTS.items():
            if name not in topics:
                continue
            policies = list(sub)
            if name == "occupancy":
                policies = [
                    Policy.Reliability.Reliable(duration(seconds=1)),
                    Policy.History.KeepLast(10),
                    Policy.Durability.TransientLocal,
                ]
            topic = Topic(self.dp, f"rt/tre/{name}", kind)

            reader = DataReader(self.dp, topic, qos=Qos(*policies, XCDR1))
            self.readers.append((name, reader))
        self.first = self.readers[0][1]
        # Taken on a thread of the peer's own, so Cyclone's receive threads never wait on Python.
        self.running = True
        self.taker = threading.Thread(target=self._take, args=(tally,), daemon=True)
        self.taker.start()

    def _take(self, tally) -> None:
        while self.running:
            idle = True
            for name, reader in self.readers:
                for m in reader.take(N=16):
                    idle = False
                    tally.arrive(name, (m.header.stamp.sec, m.header.stamp.nanosec))
            if idle:
                time.sleep(0.002)

    def _writer(self, name: str, kind, qos: Qos) -> DataWriter:
        return DataWriter(self.dp, Topic(self.dp, name, kind), qos=qos)

    def matched(self) -> bool:
        return (
            bool(self.depth.get_matched_subscriptions())
            and bool(self.info.get_matched_subscriptions())
            and bool(self.odom.get_matched_subscriptions())
            and bool(self.first.get_matched_publications())
        )

    def publish(self, stamp, w, h, depth, k, pose) -> None:
        fx, fy, cx, cy = k
        head = Header(Time(*stamp), "camera_depth_optical_frame")
        self.info.write(
            CameraInfo(
                head,
                h,
                w,
                "plumb_bob",
                [0.0] * 5,
                [fx, 0.0, cx, 0.0, fy, cy, 0.0, 0.0, 1.0],
                [1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0],
                [fx, 0.0, cx, 0.0, 0.0, fy, cy, 0.0, 0.0, 0.0, 1.0, 0.0],
            )
        )
        (t, q) = pose
        self.odom.write(
            Odometry(
                Header(Time(*stamp), "world"),
                "camera_depth_optical_frame",
                PoseWithCovariance(Pose(Point(*t), Quaternion(*q)), [0.0] * 36),
            )
        )
        # The depth image is serialised before the run (prepare) and its stamp written in
        # place, so the peer's own cost does not bound the rate (the stamp is the first field
        # after the 4-byte encapsulation header).
        ser = self.prepare(w, h, depth)
        struct.pack_into("<iI", ser, 4, stamp[0], stamp[1])
        if ddspy_write(self.depth._ref, bytes(ser)) < 0:
            raise RuntimeError("writing the depth image failed")

    def prepare(self, w: int, h: int, depth: bytes) -> bytearray:
        """The depth image's CDR, made once per frame."""
        ser = self.serialised.get(id(depth))
        if ser is None:
            head = Header(Time(0, 0), "camera_depth_optical_frame")
            ser = bytearray(
                Image(head, h, w, "16UC1", 0, 2 * w, depth).serialize(use_version_2=False)
            )
            ser.extend(b"\0" * (-len(ser) % 4))
            self.serialised[id(depth)] = ser
        return ser

    def close(self) -> None:
        self.running = False
        self.taker.join()
