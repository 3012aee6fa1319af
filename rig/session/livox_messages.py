"""Livox ``CustomMsg`` point clouds: their message types and their conversion to :class:`Scan`.

FAST-LIO, Point-LIO and ImMesh users record Livox LiDARs as ``CustomMsg`` rather than
``PointCloud2``. The same definition ships in three packages: ``livox_ros_driver`` (ROS 1,
github.com/Livox-SDK/livox_ros_driver, msg/CustomMsg.msg and msg/CustomPoint.msg at commit
3d240d5), ``livox_ros_driver2`` (ROS 1 and 2, github.com/Livox-SDK/livox_ros_driver2, msg/ at
13eb05e) and ``livox_interfaces`` (github.com/Livox-SDK/livox_ros2_driver, at 249be89).

ROS 1 bags and rosbag2 MCAP files carry their message definitions, but rosbag2 sqlite3 bags written
before ROS 2 Iron do not: a reader must know these types itself (:func:`register_livox_types`).
"""

from __future__ import annotations

from typing import Any

import numpy as np
from rosbags.typesys import get_types_from_msg

from rig.errors import InputError
from rig.messages import Scan

CUSTOM_MSG_TYPES = (
    "livox_ros_driver/msg/CustomMsg",
    "livox_ros_driver2/msg/CustomMsg",
    "livox_interfaces/msg/CustomMsg",
)

# ``Header`` resolves to std_msgs/msg/Header of the typestore it is registered in (ROS 1 with seq,
# ROS 2 without), as in the drivers' own builds.
_CUSTOM_MSG = """\
std_msgs/Header header
uint64 timebase
uint32 point_num
uint8 lidar_id
uint8[3] rsvd
CustomPoint[] points
"""
_CUSTOM_POINT = """\
uint32 offset_time
float32 x
float32 y
float32 z
uint8 reflectivity
uint8 tag
uint8 line
"""


def register_livox_types(typestore: Any) -> None:
    """Add ``CustomMsg`` and ``CustomPoint`` of every Livox package to a rosbags ``typestore``
    (a no-op for types it already has with the same definition)."""
    types: dict[str, Any] = {}
    for msgtype in CUSTOM_MSG_TYPES:
        package = msgtype.split("/", 1)[0]
        types.update(get_types_from_msg(_CUSTOM_MSG, msgtype))
        types.update(get_types_from_msg(_CUSTOM_POINT, f"{package}/msg/CustomPoint"))
    typestore.register(types)


def custom_msg_to_scan(msg: Any, t_host: int, t_device: int | None, lidar_id: str) -> Scan:
    """A :class:`Scan` from a Livox ``CustomMsg``.

    Point times are ``offset_time`` (ns) after the header stamp, as FAST-LIO reads them: the
    drivers set the stamp to ``timebase``, and a bag whose headers were re-stamped keeps its offsets
    meaningful. Points at the origin (no return) and non-finite points are dropped; a ``point_num``
    that disagrees with the points present is refused.
    """
    points = msg.points
    if int(msg.point_num) != len(points):
        raise InputError(
            f"CustomMsg says point_num={msg.point_num} but holds {len(points)} points "
            "(expected them to agree)",
            field=lidar_id,
        )
    table = np.array(
        [(p.x, p.y, p.z, p.reflectivity, p.offset_time) for p in points], dtype=np.float64
    ).reshape(-1, 5)
    xyz = table[:, :3].astype(np.float32)
    keep = np.isfinite(xyz).all(axis=1) & xyz.any(axis=1)
    return Scan(
        xyz[keep],
        (table[keep, 4] * 1e-9).astype(np.float32),
        table[keep, 3].astype(np.float32),
        t_host,
        t_device,
        lidar_id,
    )
