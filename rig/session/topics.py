"""Finding the camera, camera-info, LiDAR and IMU topics of a session by message type."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

from rig.errors import InputError
from rig.session.reader import SessionReader
from rig.session.ros_messages import CAMERA_INFO, COMPRESSED_IMAGE, IMAGE, IMU, POINT_CLOUD
from rig.session.writer import DEFAULT_TOPICS


@dataclass(frozen=True)
class SessionTopics:
    """The topic of each role (None: the session has none; calib.yaml may hold the camera model)."""

    image: str
    camera_info: str | None
    points: str | None
    imu: str | None


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


def find_topics(
    reader: SessionReader,
    image: str | None = None,
    points: str | None = None,
    camera_info: str | None = None,
    imu: str | None = None,
    *,
    require_points: bool = True,
) -> SessionTopics:
    """The topics of a session: the image and point-cloud topics must be unique unless chosen
    (points may be absent when ``require_points`` is False); camera info is the chosen or first
    CameraInfo topic. The IMU is never guessed by type (a camera's IMU is not the LiDAR's): it is
    the chosen topic, else the recorder's default IMU topic if present."""
    topics = reader.topics()

    def of_type(*msgtypes: str) -> list[str]:
        return sorted(t for t, s in topics.items() if s.msgtype in msgtypes)

    clouds = of_type(POINT_CLOUD)
    infos = of_type(CAMERA_INFO)
    imus = of_type(IMU)
    if camera_info is not None:
        camera_info = _only(infos, "camera info", reader.path, camera_info, DEFAULT_TOPICS["camera_info"])
    if imu is not None and imu not in imus:
        raise InputError(f"no IMU topic {imu!r}; the session has {imus or 'none'}", path=reader.path)
    return SessionTopics(
        image=_only(of_type(IMAGE, COMPRESSED_IMAGE), "image", reader.path, image, DEFAULT_TOPICS["image"]),
        camera_info=camera_info or (infos[0] if infos else None),
        points=(
            _only(clouds, "point cloud", reader.path, points, DEFAULT_TOPICS["points"])
            if clouds or require_points or points is not None
            else None
        ),
        imu=imu or (DEFAULT_TOPICS["imu"] if DEFAULT_TOPICS["imu"] in imus else None),
    )
