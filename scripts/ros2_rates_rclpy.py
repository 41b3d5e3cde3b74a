"""The ROS 2 peer of scripts/ros2_rates.py as a real ROS 2 node: rclpy over eProsima Fast DDS.

rclpy, rmw_fastrtps_cpp and the message packages of ROS 2 Kilted, from PyPI (the `ros-*` wheels,
scripts/requirements-rclpy.txt): the default middleware of ROS 2 with its default settings. It
publishes with the default publisher profile and subscribes with the default one (reliable, keep
the last 10) or the sensor-data one (best effort, keep 5). Messages are taken serialised (raw)
and only their stamp is read, so the peer's own cost stays small. grid_map_msgs is not among
those wheels: the grid map is counted by the Cyclone DDS peer only.
"""

from __future__ import annotations

import struct
import threading

import rclpy
from nav_msgs.msg import OccupancyGrid, Odometry
from rclpy.executors import SingleThreadedExecutor
from rclpy.qos import (
    DurabilityPolicy,
    HistoryPolicy,
    QoSProfile,
    ReliabilityPolicy,
    qos_profile_sensor_data,
)
from sensor_msgs.msg import CameraInfo, CompressedImage, Image


class Peer:
    """Publishes depth, camera_info and odometry; counts the node's outputs into `tally`."""

    def __init__(self, domain: int, reliable: bool, tally, topics: list[str]) -> None:
        self.context = rclpy.Context()
        rclpy.init(context=self.context, domain_id=domain)
        self.node = rclpy.create_node("tre_rates_peer", context=self.context)
        n = self.node
        self.depth = n.create_publisher(Image, "/camera/depth/image_rect_raw", 10)
        self.info = n.create_publisher(CameraInfo, "/camera/depth/camera_info", 10)
        self.odom = n.create_publisher(Odometry, "/odom", 10)
        sub = QoSProfile(depth=10) if reliable else qos_profile_sensor_data
        # Nav2's map profile, but keeping 10 (not 1) so that every grid is counted.
        latched = QoSProfile(
            depth=10,
            reliability=ReliabilityPolicy.RELIABLE,
            durability=DurabilityPolicy.TRANSIENT_LOCAL,
            history=HistoryPolicy.KEEP_LAST,
        )

        def counter(name: str):
            # CDR: a 4-byte encapsulation header, then the header's stamp (sec, nanosec).
            return lambda raw: tally.arrive(name, struct.unpack_from("<iI", raw, 4))

        kinds = {"occupancy": OccupancyGrid}
        for name in ("roughness", "uncertainty", "traversal"):
            kinds[name] = Image
            kinds[f"{name}/compressed"] = CompressedImage
        self.subs = [
            n.create_subscription(
                kinds[t], f"/tre/{t}", counter(t), latched if t == "occupancy" else sub, raw=True
            )
            for t in topics
            if t in kinds
        ]
        self.messages: dict[int, Image] = {}
        self.executor = SingleThreadedExecutor(context=self.context)
        self.executor.add_node(n)
        self.spinner = threading.Thread(target=self.executor.spin, daemon=True)
        self.spinner.start()

    def matched(self) -> bool:
        return (
            self.depth.get_subscription_count() > 0
            and self.info.get_subscription_count() > 0
            and self.odom.get_subscription_count() > 0
            and self.node.count_publishers("/tre/occupancy") > 0
        )

    def prepare(self, w: int, h: int, depth: bytes) -> Image:
        """The depth image's message, made once per frame (only its stamp changes)."""
        m = self.messages.get(id(depth))
        if m is None:
            m = Image(height=h, width=w, encoding="16UC1", is_bigendian=0, step=2 * w)
            m.data = depth
            m.header.frame_id = "camera_depth_optical_frame"
            self.messages[id(depth)] = m
        return m

    def publish(self, stamp, w, h, depth, k, pose) -> None:
        fx, fy, cx, cy = k
        info = CameraInfo(height=h, width=w, distortion_model="plumb_bob")
        info.header.stamp.sec, info.header.stamp.nanosec = stamp
        info.header.frame_id = "camera_depth_optical_frame"
        info.d = [0.0] * 5
        info.k = [fx, 0.0, cx, 0.0, fy, cy, 0.0, 0.0, 1.0]
        info.r = [1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0]
        info.p = [fx, 0.0, cx, 0.0, 0.0, fy, cy, 0.0, 0.0, 0.0, 1.0, 0.0]
        self.info.publish(info)
        odom = Odometry(child_frame_id="camera_depth_optical_frame")
        odom.header.stamp.sec, odom.header.stamp.nanosec = stamp
        odom.header.frame_id = "world"
        (t, q) = pose
        p = odom.pose.pose
        p.position.x, p.position.y, p.position.z = t
        p.orientation.x, p.orientation.y, p.orientation.z, p.orientation.w = q
        self.odom.publish(odom)
        m = self.prepare(w, h, depth)
        m.header.stamp.sec, m.header.stamp.nanosec = stamp
        self.depth.publish(m)

    def close(self) -> None:
        self.executor.shutdown()
        self.spinner.join(timeout=5)
        for s in self.subs:
            self.node.destroy_subscription(s)
        for p in (self.depth, self.info, self.odom):
            self.node.destroy_publisher(p)
        self.node.destroy_node()
        rclpy.shutdown(context=self.context)
