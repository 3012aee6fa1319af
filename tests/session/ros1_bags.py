"""Small ROS 1 bags written message by message, for the tests of the bag readers."""

from __future__ import annotations

from collections.abc import Iterable
from pathlib import Path
from typing import Any

import numpy as np
from rosbags.rosbag1 import Writer
from rosbags.typesys import Stores, get_typestore

STORE = get_typestore(Stores.ROS1_NOETIC)
TYPES = STORE.types


def header(stamp_ns: int, frame_id: str = "sensor") -> Any:
    sec, nanosec = divmod(int(stamp_ns), 1_000_000_000)
    return TYPES["std_msgs/msg/Header"](
        seq=0, stamp=TYPES["builtin_interfaces/msg/Time"](sec=sec, nanosec=nanosec), frame_id=frame_id
    )


def image(stamp_ns: int, frame_id: str = "camera_optical_frame") -> Any:
    """A 4x6 mono8 ``Image``."""
    return TYPES["sensor_msgs/msg/Image"](
        header=header(stamp_ns, frame_id),
        height=4,
        width=6,
        encoding="mono8",
        is_bigendian=0,
        step=6,
        data=np.full(24, 128, dtype=np.uint8),
    )


def cloud(stamp_ns: int, frame_id: str = "lidar") -> Any:
    """A ``PointCloud2`` of 3 points (x y z float32)."""
    points = np.array([[1, 0, 0], [0, 2, 0], [0, 0, 3]], dtype="<f4")
    field = TYPES["sensor_msgs/msg/PointField"]
    return TYPES["sensor_msgs/msg/PointCloud2"](
        header=header(stamp_ns, frame_id),
        height=1,
        width=3,
        fields=[field(name=n, offset=4 * i, datatype=7, count=1) for i, n in enumerate("xyz")],
        is_bigendian=False,
        point_step=12,
        row_step=36,
        data=points.view(np.uint8).reshape(-1),
        is_dense=True,
    )


def text(value: str) -> Any:
    """A ``std_msgs/String`` (no header)."""
    return TYPES["std_msgs/msg/String"](data=value)


def write_ros1_bag(path: Path, messages: Iterable[tuple[str, int, Any]]) -> Path:
    """A ROS 1 bag of ``(topic, receive time ns, message)`` (ROS 1 Noetic types)."""
    with Writer(path) as writer:
        connections: dict[str, Any] = {}
        for topic, t_receive, msg in messages:
            if topic not in connections:
                connections[topic] = writer.add_connection(topic, msg.__msgtype__, typestore=STORE)
            writer.write(connections[topic], t_receive, STORE.serialize_ros1(msg, msg.__msgtype__))
    return path
