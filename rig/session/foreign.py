"""Others' recordings through a role → topic map, as the toolkit's types: what the mapper imports
(odometry, registered clouds) and the Ouster packet reader use.

Bags are opened with :func:`rig.session.recording.open_recording`, the one reader of bags in the
toolkit: ``t_host`` is a message's header stamp (else the bag's receive time, see
:mod:`rig.session.stamps`) and ``t_device`` is None; our own sessions keep their two clocks.
"""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from rig.errors import InputError
from rig.session import ros_messages as rm
from rig.session.recording import open_recording
from rig.session.topic_map import UT_MM_TOPICS
from rig.session.topics import listing
from rig.trajectory import Trajectory

__all__ = [
    "ROLES",
    "UT_MM_TOPICS",
    "ForeignMessage",
    "list_topics",
    "raw_messages",
    "read_foreign",
    "read_foreign_trajectory",
]

ROLES = ("image", "camera_info", "points", "imu", "pose")
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


def raw_messages(path: str | Path, topics: set[str]) -> Iterator[tuple[str, str, int, Any]]:
    """``(topic, msgtype, time ns, message)`` of ``topics`` in file order (rosbags types)."""
    for m in open_recording(path).messages(topics):
        yield m.topic, m.msgtype, m.t_host, m.msg


def list_topics(path: str | Path) -> dict[str, tuple[str, int]]:
    """``{topic: (msgtype, count)}`` of a bag, rosbag2 folder or MCAP file."""
    return open_recording(path).topic_types()


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
    bad = sorted(set(topic_map) - set(ROLES))
    if bad:
        raise InputError(f"unknown role(s) {bad}; expected some of {ROLES}", field="topic_map")
    recording = open_recording(path)
    available = recording.topic_types()
    missing = sorted(t for t in topic_map.values() if t not in available)
    if missing:
        raise InputError(
            f"topic(s) {missing} not in the bag; it has: {listing(available)}", path=recording.path
        )
    role_of = {topic: role for role, topic in topic_map.items()}
    for m in recording.messages(set(role_of)):
        role, msg, topic = role_of[m.topic], m.msg, m.topic
        if role == "image":
            value: Any = rm.msg_to_frame(msg, m.msgtype, m.t_host, m.t_device, topic)
        elif role == "points":
            value = rm.msg_to_scan(msg, m.t_host, m.t_device, topic)
        elif role == "imu":
            value = rm.msg_to_imu(msg, m.t_host, m.t_device, topic)
        elif role == "camera_info":
            value = rm.msg_to_camera(msg)
        elif m.msgtype.rsplit("/", 1)[-1] in _POSE_TYPES:
            value = _pose_matrix(msg, m.msgtype)
        else:
            raise InputError(
                f"{m.msgtype} cannot be read as a pose (expected {_POSE_TYPES})", path=path, field=topic
            )
        yield ForeignMessage(role, topic, m.t_host, m.t_device, value)


def read_foreign_trajectory(path: str | Path, topic: str) -> Trajectory:
    """The poses of ``topic`` (PoseStamped, PoseWithCovarianceStamped or Odometry), by header stamp."""
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
