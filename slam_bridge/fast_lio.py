"""Import of FAST-LIO output: the saved point map (``scans.pcd``) and the odometry topic.

FAST-LIO keeps no mesh, so one is made from the map (:mod:`slam_bridge.point_map`). Poses are
FAST-LIO's body (IMU) poses in its ``camera_init`` world frame.
"""

from __future__ import annotations

from pathlib import Path

from rig.errors import InputError
from rig.pointcloud_io import read_point_cloud
from rig.trajectory import Trajectory
from rig.trajectory_io import read_trajectory
from slam_bridge.mapper_bag import find_bag, read_odometry
from slam_bridge.mesh_cleanup import CleanupReport
from slam_bridge.point_map import mesh_from_points
from slam_bridge.slam_dir import write_slam_dir

ODOMETRY_TOPIC = "/Odometry"


def _find_map(folder: Path) -> Path:
    for candidate in (folder / "scans.pcd", folder / "PCD" / "scans.pcd"):
        if candidate.is_file():
            return candidate
    raise InputError("no scans.pcd or PCD/scans.pcd (FAST-LIO saves it with pcd_save_en)", path=folder)


def _find_trajectory(folder: Path, bag: Path | None, topic: str) -> Trajectory:
    bag = bag or find_bag(folder)
    if bag is None:
        raise InputError(
            "no bag with the odometry topic in the folder; pass --bag or --trajectory", path=folder
        )
    return read_odometry(bag, topic)


def import_fast_lio(
    folder: str | Path,
    out_dir: str | Path,
    trajectory_path: str | Path | None = None,
    odometry_topic: str = ODOMETRY_TOPIC,
    bag: str | Path | None = None,
) -> CleanupReport:
    """Import FAST-LIO's map and odometry into ``out_dir/{mesh.ply, trajectory.tum}``.

    The odometry comes from ``trajectory_path`` (any trajectory file), else from ``bag`` or the
    one bag in ``folder`` (topic ``odometry_topic``, nav_msgs/Odometry).
    """
    folder = Path(folder)
    trajectory = (
        read_trajectory(trajectory_path)
        if trajectory_path
        else _find_trajectory(folder, Path(bag) if bag else None, odometry_topic)
    )
    cloud = read_point_cloud(_find_map(folder))
    return write_slam_dir(out_dir, mesh_from_points(cloud.points, trajectory.translations), trajectory)[1]
