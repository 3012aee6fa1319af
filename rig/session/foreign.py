"""Reading other people's recordings: ROS 1 bags, rosbag2 folders and bare MCAP files.

A *topic map* says which foreign topic plays which role (``image``, ``camera_info``, ``points``,
``imu``, ``pose``). Messages come back as the toolkit's types, with ``t_host`` = the time the bag
recorded the message and ``t_device`` = its header stamp. ROS 1 bags and rosbag2 folders are read
with rosbags' ``AnyReader``; a bare ``.mcap`` (no ``metadata.yaml``) with :class:`SessionReader`.
"""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from rig.errors import InputError
from rig.session import ros_messages as rm
from rig.session.reader import SessionReader
from rig.trajectory import Trajectory

ROLES = ("image", "camera_info", "points", "imu", "pose")
#: Topic map of the UT-MM dataset's bags.
UT_MM_TOPICS = {
    "image": "/realsense/color/image_raw/compressed",
    "camera_info": "/realsense/color/camera_info",
    "points": "/ouster/points",
    "imu": "/ouster/imu",
}
_POSE_TYPES = ("PoseStamped", "PoseWithCovarianceStamped", "Odometry")


@dataclass(frozen=True)
class ForeignMessage:
    """One message of a mapped topic: ``value`` is a Frame, Scan, ImuSample, CameraModel or a
    ``(4, 4)`` pose ``T_world_body`` (role ``pose``)."""

    role: str
    topic: str
    t_host: int
    t_device: int | None
    value: Any


def raw_messages(path: Path, topics: set[str]) -> Iterator[tuple[str, str, int, Any]]:
    """``(topic, msgtype, log time ns, message)`` of ``topics`` in bag order (rosbags types)."""
    if path.is_file() and path.suffix == ".mcap":
        for m in SessionReader(path).messages(topics):
            yield m.topic, m.msgtype, m.t_host, m.msg
        return
    from rosbags.highlevel import AnyReader
    from rosbags.highlevel.anyreader import AnyReaderError

    try:
        with AnyReader([path], default_typestore=rm.typestore()) as reader:
            conns = [c for c in reader.connections if c.topic in topics]
            for conn, t, raw in reader.messages(connections=conns):
                yield conn.topic, conn.msgtype, int(t), reader.deserialize(raw, conn.msgtype)
    except AnyReaderError as exc:
        raise InputError(f"cannot read bag: {exc}", path=path) from exc


def list_topics(path: str | Path) -> dict[str, tuple[str, int]]:
    """``{topic: (msgtype, count)}`` of a bag, rosbag2 folder or MCAP file."""
    path = Path(path)
    if not path.exists():
        raise InputError("no such bag", path=path)
    if path.is_file() and path.suffix == ".mcap":
        return {k: (v.msgtype, v.count) for k, v in SessionReader(path).topics().items()}
    from rosbags.highlevel import AnyReader
    from rosbags.highlevel.anyreader import AnyReaderError

    try:
        with AnyReader([path], default_typestore=rm.typestore()) as reader:
            return {c.topic: (c.msgtype, c.msgcount) for c in reader.connections}
    except AnyReaderError as exc:
        raise InputError(f"cannot read bag: {exc}", path=path) from exc


def _pose_matrix(msg: Any, msgtype: str) -> np.ndarray:
    from rig.transforms import from_quaternion

    pose = msg.pose.pose if msgtype.endswith(("Odometry", "PoseWithCovarianceStamped")) else msg.pose
    q, p = pose.orientation, pose.position
    return from_quaternion(np.array([q.x, q.y, q.z, q.w]), np.array([p.x, p.y, p.z]))


def read_foreign(path: str | Path, topic_map: dict[str, str]) -> Iterator[ForeignMessage]:
    """Messages of the mapped topics in bag order, converted to the toolkit's types.

    Args:
        path: ROS 1 ``.bag``, rosbag2 folder, or ``.mcap`` file.
        topic_map: ``{role: topic}`` with roles from :data:`ROLES`.
    """
    path = Path(path)
    bad = sorted(set(topic_map) - set(ROLES))
    if bad:
        raise InputError(f"unknown role(s) {bad}; expected some of {ROLES}", field="topic_map")
    available = list_topics(path)
    missing = sorted(t for t in topic_map.values() if t not in available)
    if missing:
        raise InputError(f"topic(s) {missing} not in the bag (it has {sorted(available)})", path=path)
    role_of = {topic: role for role, topic in topic_map.items()}
    for topic, msgtype, t_log, msg in raw_messages(path, set(role_of)):
        role = role_of[topic]
        stamp = rm.stamp_ns(msg) if hasattr(msg, "header") else None
        name = msgtype.rsplit("/", 1)[-1]
        if role == "image":
            value: Any = rm.msg_to_frame(msg, msgtype, t_log, stamp, topic)
        elif role == "points":
            value = rm.msg_to_scan(msg, t_log, stamp, topic)
        elif role == "imu":
            value = rm.msg_to_imu(msg, t_log, stamp, topic)
        elif role == "camera_info":
            value = rm.msg_to_camera(msg)
        elif name in _POSE_TYPES:
            value = _pose_matrix(msg, msgtype)
        else:
            raise InputError(
                f"{msgtype} cannot be read as a pose (expected {_POSE_TYPES})", path=path, field=topic
            )
        yield ForeignMessage(role, topic, t_log, stamp, value)


def read_foreign_trajectory(path: str | Path, topic: str) -> Trajectory:
    """The poses of ``topic`` (PoseStamped, PoseWithCovarianceStamped or Odometry), stamped by header."""
    from rig.transforms import to_quaternion

    t, trans, quats = [], [], []
    for m in read_foreign(path, {"pose": topic}):
        t.append(m.t_device if m.t_device is not None else m.t_host)
        trans.append(m.value[:3, 3])
        quats.append(to_quaternion(m.value))
    if not t:
        raise InputError("no poses on the topic", path=path, field=topic)
    order = np.argsort(np.asarray(t), kind="stable")
    return Trajectory.from_quaternions(
        np.asarray(t, dtype=np.int64)[order],
        np.asarray(trans)[order],
        np.asarray(quats)[order],
        source=str(path),
    )
