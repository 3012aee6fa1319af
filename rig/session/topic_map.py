"""Topic maps: which topic of a recording plays which role.

A map is written as ``role=topic`` pairs (``image=/cam/image_raw/compressed,points=/os_cloud_node/points``),
as a YAML file with the same keys, as a preset name, or as ``auto`` (every role found by message
type, see :func:`rig.session.find_topics`). Roles a map leaves out are found by type as well.
"""

from __future__ import annotations

from pathlib import Path

from rig.errors import InputError

ROLES = ("image", "camera_info", "points", "imu")

#: The UT-MM dataset's bags (ROS 1): RealSense colour camera, Ouster OS1 with its IMU.
UT_MM_TOPICS = {
    "image": "/realsense/color/image_raw/compressed",
    "camera_info": "/realsense/color/camera_info",
    "points": "/ouster/points",
    "imu": "/ouster/imu",
}
#: The Newer College dataset's stereo-camera collection (2020, ROS 1 bags split into parts):
#: Ouster OS1-64 on /os1_cloud_node (points, and its IMU), Intel RealSense D435i infrared camera 1
#: (mono8 sensor_msgs/Image). Sources: ori-drs.github.io/newer-college-dataset/stereo-cam, and the
#: topic names as public readers of those bags use them: github.com/contagon/evalio
#: (NewerCollege2020), github.com/v4rl-ucy/ellipselio (config/os64_ncd.yaml), github.com/koide3/glim_ros1
#: (an earlier src/glim_rosbag.cpp: /os1_cloud_node/imu, /os1_cloud_node/points,
#: /camera/infra1/image_rect_raw/compressed in the dataset's compressed copy). The camera info is
#: left to be found next to the image topic.
NEWER_COLLEGE_TOPICS = {
    "image": "/camera/infra1/image_rect_raw",
    "points": "/os1_cloud_node/points",
    "imu": "/os1_cloud_node/imu",
}
PRESETS = {"ut-mm": UT_MM_TOPICS, "newer-college": NEWER_COLLEGE_TOPICS}

#: What ``--topics`` accepts, for the commands' help texts.
TOPICS_HELP = (
    "Which topic plays which role: ROLE=TOPIC pairs separated by commas (roles: "
    + ", ".join(ROLES)
    + "), a YAML file with those keys, a preset ("
    + ", ".join(PRESETS)
    + ") or auto: each role found by message type where the recording has one topic of that type "
    "(else an error lists the candidates). Roles left out are found by type."
)


def parse_topic_map(spec: str | None) -> dict[str, str]:
    """``{role: topic}`` from a ``--topics`` value (None or ``auto``: empty)."""
    if spec is None or spec.strip() in ("", "auto"):
        return {}
    spec = spec.strip()
    if spec in PRESETS:
        return dict(PRESETS[spec])
    if "=" in spec:
        pairs = [item.partition("=") for item in spec.split(",") if item.strip()]
        bad = [role for role, sep, topic in pairs if not sep or not topic.strip()]
        if bad:
            raise InputError(f"expected ROLE=TOPIC pairs, got {spec!r}", field="--topics")
        return _checked({role.strip(): topic.strip() for role, _, topic in pairs}, "--topics")
    if Path(spec).is_file():
        from rig.data_file import load_data_file

        data = load_data_file(spec, "YAML", "topic map")
        if not isinstance(data, dict) or not all(isinstance(v, str) for v in data.values()):
            raise InputError("expected a mapping of roles to topic names", path=spec)
        try:
            return _checked({str(k): v for k, v in data.items()}, "roles")
        except InputError as exc:
            raise InputError(exc.reason, path=spec) from None
    raise InputError(
        f"unknown topic map {spec!r}: expected ROLE=TOPIC pairs, a YAML file, a preset "
        f"({', '.join(PRESETS)}) or auto",
        field="--topics",
    )


def _checked(topic_map: dict[str, str], field: str) -> dict[str, str]:
    unknown = sorted(set(topic_map) - set(ROLES))
    if unknown:
        raise InputError(
            f"unknown role(s) {', '.join(unknown)}; expected some of {', '.join(ROLES)}", field=field
        )
    return topic_map
