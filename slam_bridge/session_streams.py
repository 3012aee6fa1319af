"""Finding the camera, camera-info and LiDAR topics of a session."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

from rig.errors import InputError
from rig.session import SessionReader
from rig.session.ros_messages import CAMERA_INFO, COMPRESSED_IMAGE, IMAGE, POINT_CLOUD
from rig.session.writer import DEFAULT_TOPICS


@dataclass(frozen=True)
class SessionTopics:
    """The topics a reconstruction reads (``camera_info`` may be None: calib.yaml has the model)."""

    image: str
    camera_info: str | None
    points: str


def _only(candidates: list[str], kind: str, path: Path, chosen: str | None, default: str) -> str:
    """The chosen topic, else the only candidate, else the recorder's default topic for this kind
    (``rig record`` writes the 3D LiDAR to ``/lidar/points`` beside e.g. a 2D scanner's topic)."""
    if chosen is not None:
        if chosen not in candidates:
            raise InputError(f"no {kind} topic {chosen!r}; the session has {candidates or 'none'}", path=path)
        return chosen
    if len(candidates) > 1 and default in candidates:
        return default
    if len(candidates) != 1:
        raise InputError(
            f"expected one {kind} topic, found {len(candidates)} ({', '.join(candidates) or 'none'}); "
            "choose one with the topic option",
            path=path,
        )
    return candidates[0]


def find_topics(reader: SessionReader, image: str | None = None, points: str | None = None) -> SessionTopics:
    """The image and point-cloud topics of a session (each must be unique unless chosen)."""
    topics = reader.topics()
    images = sorted(t for t, s in topics.items() if s.msgtype in (IMAGE, COMPRESSED_IMAGE))
    clouds = sorted(t for t, s in topics.items() if s.msgtype == POINT_CLOUD)
    infos = sorted(t for t, s in topics.items() if s.msgtype == CAMERA_INFO)
    return SessionTopics(
        _only(images, "image", reader.path, image, DEFAULT_TOPICS["image"]),
        infos[0] if infos else None,
        _only(clouds, "point cloud", reader.path, points, DEFAULT_TOPICS["points"]),
    )
