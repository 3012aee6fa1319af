"""The calibration a bag already carries: the LiDAR-camera extrinsic from its ``/tf_static``
transforms and the camera model from its ``CameraInfo``.

``T_cam_lidar`` is composed along the static transform tree from the point cloud's header frame
to the image's header frame. REP 103 has the image's ``frame_id`` be the camera's *optical* frame
(x right, y down, z forward: the OpenCV frame this toolkit uses); a driver that stamps images with
a body frame (x forward) gives an extrinsic turned by that frame change, which the targetless
refinement of ``lts calibrate`` cannot undo, so check ``frame_id`` when the overlay looks wrong.
"""

from __future__ import annotations

from collections import deque
from dataclasses import dataclass

import numpy as np

from rig.calibration import Calibration
from rig.errors import InputError
from rig.session.source import Recording
from rig.session.topics import SessionTopics
from rig.transforms import from_quaternion, invert

TF_STATIC = "/tf_static"


@dataclass(frozen=True)
class TfExtrinsic:
    """``T_cam_lidar`` ``(4, 4)`` from ``/tf_static``, between the named header frames."""

    T_cam_lidar: np.ndarray
    camera_frame: str
    lidar_frame: str

    def describe(self) -> str:
        return f"{TF_STATIC} ({self.lidar_frame} -> {self.camera_frame})"


def static_transforms(recording: Recording) -> dict[tuple[str, str], np.ndarray]:
    """``{(parent, child): T_parent_child (4, 4)}`` of every ``/tf_static`` message of the whole
    recording (static transforms are published once, at the start)."""
    edges: dict[tuple[str, str], np.ndarray] = {}
    for m in recording.messages([TF_STATIC], whole=True):
        for tf in getattr(m.msg, "transforms", []):
            q, p = tf.transform.rotation, tf.transform.translation
            T = from_quaternion(np.array([q.x, q.y, q.z, q.w]), np.array([p.x, p.y, p.z]))
            edges[(_frame(tf.header.frame_id), _frame(tf.child_frame_id))] = T
    return edges


def lookup(edges: dict[tuple[str, str], np.ndarray], target: str, source: str) -> np.ndarray | None:
    """``T_target_source`` ``(4, 4)`` composed along the tree of ``edges``; None when the two
    frames are not connected."""
    links: dict[str, list[tuple[str, np.ndarray]]] = {}
    for (parent, child), T in edges.items():
        links.setdefault(child, []).append((parent, T))  # T_parent_child: child -> parent
        links.setdefault(parent, []).append((child, invert(T)))
    reached = {source: np.eye(4)}  # T_frame_source
    queue = deque([source])
    while queue:
        frame = queue.popleft()
        for neighbour, T_neighbour_frame in links.get(frame, []):
            if neighbour not in reached:
                reached[neighbour] = T_neighbour_frame @ reached[frame]
                queue.append(neighbour)
    return reached.get(target)


def header_frame(recording: Recording, topic: str) -> str:
    """``header.frame_id`` of the first message on ``topic``."""
    for m in recording.messages([topic], whole=True):
        return _frame(m.msg.header.frame_id)
    raise InputError("no messages", path=recording.path, field=topic)


def tf_extrinsic(recording: Recording, topics: SessionTopics) -> TfExtrinsic | None:
    """``T_cam_lidar`` from ``/tf_static`` between the image's and the point cloud's header
    frames; None when the recording has no such transform chain."""
    if (
        topics.image is None
        or topics.points is None
        or (recording.span is None and TF_STATIC not in recording.topic_types())
    ):
        return None  # (a span may start after the transforms: they are then read from the whole file)
    edges = static_transforms(recording)
    if not edges:
        return None
    camera_frame = header_frame(recording, topics.image)
    lidar_frame = header_frame(recording, topics.points)
    T = lookup(edges, camera_frame, lidar_frame)
    return None if T is None else TfExtrinsic(T, camera_frame, lidar_frame)


def recording_calibration(recording: Recording, topics: SessionTopics) -> Calibration:
    """The calibration the recording carries: the camera model of its ``CameraInfo`` and the
    ``/tf_static`` extrinsic, no time offset; an error says which is missing."""
    if topics.camera_info is None:
        raise InputError(
            "the recording has no CameraInfo topic, which --calib tf needs for the camera model",
            path=recording.path,
            field="camera_info",
        )
    extrinsic = tf_extrinsic(recording, topics)
    if extrinsic is None:
        raise InputError(
            f"no {TF_STATIC} transform chain joins the image's and the point cloud's header frames, "
            "which --calib tf needs for T_cam_lidar (give a calib.yaml instead)",
            path=recording.path,
            field=TF_STATIC,
        )
    quality = {
        "source": f"CameraInfo on {topics.camera_info} and {extrinsic.describe()}",
        "time_offset": "not estimated (0 s)",
    }
    return Calibration(recording.camera_model(topics.camera_info), extrinsic.T_cam_lidar, 0.0, quality)


def _frame(name: str) -> str:
    return str(name).lstrip("/")  # ROS 1 frame ids may carry a leading slash
