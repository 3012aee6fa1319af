"""A mapper's recorded bag: finding it, and reading its odometry and registered point clouds.

A bag is a ROS 1 ``.bag``, a rosbag2 folder (``metadata.yaml`` + ``.db3``/``.mcap``) or a bare
``.mcap`` file; all are read with rosbags through :mod:`rig.session.foreign`, the reader FAST-LIO's
and ImMesh's imports share.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from rig.errors import InputError
from rig.session.foreign import list_topics, read_foreign, read_foreign_trajectory
from rig.trajectory import Trajectory

#: File endings of single-file bags (a rosbag2 folder is recognised by its ``metadata.yaml``).
BAG_SUFFIXES = (".bag", ".mcap")
#: Registered points are merged into voxels of this size (m) while a bag is read, which bounds
#: memory on long runs; meshing samples the map at 3 cm anyway.
CLOUD_VOXEL_M = 0.01
#: Merge the points read so far once this many have piled up.
_MERGE_EVERY_POINTS = 2_000_000


def is_bag(path: Path) -> bool:
    """Whether ``path`` is a bag file or a rosbag2 folder."""
    return (path.is_file() and path.suffix in BAG_SUFFIXES) or (path / "metadata.yaml").is_file()


def find_bag(folder: Path) -> Path | None:
    """The one bag at the root of ``folder``; None if there is none; an error if there are several."""
    bags = sorted(p for p in folder.iterdir() if is_bag(p))
    if len(bags) > 1:
        names = ", ".join(p.name for p in bags)
        raise InputError(f"found {len(bags)} bags ({names}); pass --bag to choose one", path=folder)
    return bags[0] if bags else None


def require_topic(bag: Path, topic: str, msgtypes: tuple[str, ...], option: str) -> None:
    """Raise :class:`InputError` naming the bag, the topic and the bag's topics unless ``topic``
    exists with one of ``msgtypes`` (type names without package, e.g. ``Odometry``)."""
    topics = list_topics(bag)
    listing = ", ".join(f"{name} ({msgtype})" for name, (msgtype, _) in sorted(topics.items())) or "none"
    if topic not in topics:
        raise InputError(
            f"no topic {topic} in the bag; it has: {listing}. Pass {option} to choose another",
            path=bag,
            field=topic,
        )
    msgtype = topics[topic][0]
    if msgtype.rsplit("/", 1)[-1] not in msgtypes:
        raise InputError(f"{topic} holds {msgtype}, expected {' or '.join(msgtypes)}", path=bag, field=topic)


def read_odometry(bag: Path, topic: str, option: str = "--odometry-topic") -> Trajectory:
    """The body poses of an odometry topic (nav_msgs/Odometry or a PoseStamped), by header stamp."""
    require_topic(bag, topic, ("Odometry", "PoseStamped", "PoseWithCovarianceStamped"), option)
    return read_foreign_trajectory(bag, topic)


def read_registered_points(
    bag: Path, topic: str, voxel_m: float = CLOUD_VOXEL_M, option: str = "--cloud-topic"
) -> np.ndarray:
    """Every point ``(N, 3)`` of the registered clouds on ``topic`` (sensor_msgs/PointCloud2, already
    in the map frame), merged into voxels of ``voxel_m``."""
    from rig.open3d_lite import o3d

    require_topic(bag, topic, ("PointCloud2",), option)

    def merged(chunks: list[np.ndarray]) -> np.ndarray:
        cloud = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(np.concatenate(chunks).astype(np.float64)))
        return np.asarray(cloud.voxel_down_sample(voxel_m).points)

    chunks: list[np.ndarray] = []
    pending = 0
    for message in read_foreign(bag, {"points": topic}):
        chunks.append(message.value.points)
        pending += len(message.value.points)
        if pending >= _MERGE_EVERY_POINTS:
            chunks, pending = [merged(chunks)], 0
    if not chunks:
        raise InputError("no point clouds on the topic", path=bag, field=topic)
    return merged(chunks)
