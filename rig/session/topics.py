"""Finding the camera, camera-info, LiDAR and IMU topics of a recording: chosen by the user (an
option or the recording's topic map), else by message type."""

from __future__ import annotations

from dataclasses import dataclass

from rig.errors import InputError
from rig.session.ros_messages import CAMERA_INFO, COMPRESSED_IMAGE, IMAGE, IMU, POINT_CLOUD_TYPES
from rig.session.source import Recording
from rig.session.writer import DEFAULT_TOPICS

#: Message types each role accepts.
ROLE_TYPES = {
    "image": (IMAGE, COMPRESSED_IMAGE),
    "camera_info": (CAMERA_INFO,),
    "points": POINT_CLOUD_TYPES,
    "imu": (IMU,),
}
_KIND = {"image": "image", "camera_info": "camera info", "points": "point cloud", "imu": "IMU"}


@dataclass(frozen=True)
class SessionTopics:
    """The topic of each role (None: the session has none; calib.yaml may hold the camera model)."""

    image: str | None
    camera_info: str | None
    points: str | None
    imu: str | None


def listing(types: dict[str, tuple[str, int]], topics: list[str] | None = None) -> str:
    """``TOPIC (TYPE, N messages), ...`` of ``topics`` (default: all), or ``none``."""
    names = sorted(types) if topics is None else topics
    return ", ".join(f"{t} ({types[t][0]}, {types[t][1]} messages)" for t in names) or "none"


def find_topics(
    reader: Recording,
    image: str | None = None,
    points: str | None = None,
    camera_info: str | None = None,
    imu: str | None = None,
    *,
    require_points: bool = True,
    require_image: bool = True,
) -> SessionTopics:
    """The topic of each role. A topic given here wins over the recording's topic map, which wins
    over message types: the image and point-cloud topics must then be unique (or the recorder's
    default among several; either may be absent when ``require_...`` is False), the camera
    info is the one nearest the image topic's namespace, and the IMU is the recorder's default or
    the one IMU in the point cloud's namespace (a camera's IMU is not the LiDAR's). Errors list
    the candidates with their types and counts."""
    types = reader.topic_types()
    if not types and reader.span is not None:
        raise InputError(f"no messages within {reader.span.describe()}", path=reader.path)
    given = {"image": image, "points": points, "camera_info": camera_info, "imu": imu}
    chosen = {**reader.topic_map, **{role: t for role, t in given.items() if t is not None}}
    for role, topic in chosen.items():
        _check_choice(reader, types, role, topic)

    def of_role(role: str) -> list[str]:
        return sorted(t for t, (msgtype, _) in types.items() if msgtype in ROLE_TYPES[role])

    images, clouds = of_role("image"), of_role("points")
    image_topic = chosen.get("image") or (
        _only(reader, types, images, "image") if images or require_image else None
    )
    points_topic = chosen.get("points") or (
        _only(reader, types, clouds, "points") if clouds or require_points else None
    )
    imus = of_role("imu")
    imu_topic = chosen.get("imu") or (
        DEFAULT_TOPICS["imu"] if DEFAULT_TOPICS["imu"] in imus else _nearest(imus, points_topic, unique=True)
    )
    return SessionTopics(
        image=image_topic,
        camera_info=chosen.get("camera_info") or _nearest(of_role("camera_info"), image_topic, unique=False),
        points=points_topic,
        imu=imu_topic,
    )


def _check_choice(reader: Recording, types: dict[str, tuple[str, int]], role: str, topic: str) -> None:
    if topic not in types:
        raise InputError(
            f"no {_KIND[role]} topic {topic!r}; the recording has: {listing(types)}",
            path=reader.path,
            field=role,
        )
    if types[topic][0] not in ROLE_TYPES[role]:
        raise InputError(
            f"{topic} holds {types[topic][0]}; the {role} role expects {' or '.join(ROLE_TYPES[role])}",
            path=reader.path,
            field=role,
        )


def _only(reader: Recording, types: dict[str, tuple[str, int]], candidates: list[str], role: str) -> str:
    """The only candidate, else the recorder's default topic among several (``rig record``
    writes the 3D LiDAR to ``/lidar/points`` beside e.g. a 2D scanner's topic)."""
    if len(candidates) > 1 and DEFAULT_TOPICS[role] in candidates:
        return DEFAULT_TOPICS[role]
    if len(candidates) == 1:
        return candidates[0]
    found = (
        f"found {len(candidates)}: {listing(types, candidates)}"
        if candidates
        else f"found none (the recording has: {listing(types)})"
    )
    raise InputError(
        f"expected one {_KIND[role]} topic, {found}; choose with --topics {role}=TOPIC",
        path=reader.path,
        field=role,
    )


def _nearest(candidates: list[str], topic: str | None, *, unique: bool) -> str | None:
    """The candidate sharing the most leading namespace parts with ``topic``; with ``unique``,
    only one sharing at least one part and more than any other."""
    if not candidates:
        return None
    if topic is None:
        return None if unique else candidates[0]

    def shared(name: str) -> int:
        n = 0
        for a, b in zip(name.strip("/").split("/"), topic.strip("/").split("/"), strict=False):
            if a != b:
                break
            n += 1
        return n

    ranked = sorted(candidates, key=lambda c: (-shared(c), c))
    if not unique:
        return ranked[0]
    best = shared(ranked[0])
    tied = len(ranked) > 1 and shared(ranked[1]) == best
    return ranked[0] if best > 0 and not tied else None
