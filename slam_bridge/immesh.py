"""Import of ImMesh output (hku-mars/ImMesh) into a SLAM folder.

ImMesh writes, when the user presses "Save Mesh":

- ``rec_mesh.ply``: binary PLY written by PCL, xyz only; its vertex list holds every map point,
  including points no face uses, and faces may be flipped.
- ``Log/kitti_log_voxelmap.txt``: TUM-like lines ``t tx ty tz qx qy qz qw`` (6 decimals) of the
  body (IMU) pose ``T_world_body`` in ImMesh's ``camera_init`` world frame — but each pose was
  conjugated before writing, ``T_log = T_lc · T · T_lc⁻¹``, with the hard-coded KITTI
  velodyne→camera matrix :data:`T_LC` (ImMesh ``src/voxel_mapping_common.cpp``, ``kitti_log``).
  We undo it: ``T = T_lc⁻¹ · T_log · T_lc``.

A bag recorded while ImMesh ran holds the same body poses on ``/aft_mapped_to_init``
(nav_msgs/Odometry, *not* conjugated) and the registered scans on ``/cloud_registered``
(sensor_msgs/PointCloud2, already in ``camera_init``). When there is a bag, its odometry wins over
the log: it carries full double precision and exact header stamps, where the log was printed with
6 decimals after a conjugation by a matrix that is orthonormal only to ~1e-6. The log, if there
too, then checks that both come from the same run. Without ``rec_mesh.ply`` the mesh is made from
the registered clouds the way FAST-LIO's map is (:mod:`slam_bridge.point_map`).
"""

from __future__ import annotations

from dataclasses import asdict, dataclass
from pathlib import Path

import numpy as np

from rig.errors import InputError
from rig.mesh_io import load_mesh
from rig.trajectory import Trajectory
from rig.trajectory_io import read_tum
from slam_bridge.mapper_bag import find_bag, is_bag, read_odometry, read_registered_points
from slam_bridge.mesh_cleanup import CleanupReport
from slam_bridge.point_map import mesh_from_points
from slam_bridge.slam_dir import write_slam_dir

#: KITTI's velodyne→camera matrix that ImMesh's ``kitti_log`` conjugates every logged pose with.
#: (Its rotation is orthonormal only to ~1e-6, as printed in KITTI's calibration.)
T_LC = np.array(
    [
        [0.00554604, -0.999971, -0.00523653, 0.0316362],
        [-0.000379382, 0.00523451, -0.999986, 0.0380934],
        [0.999985, 0.00554795, -0.000350341, 0.409066],
        [0.0, 0.0, 0.0, 1.0],
    ]
)

MESH_NAME = "rec_mesh.ply"
LOG_NAME = "kitti_log_voxelmap.txt"
ODOMETRY_TOPIC = "/aft_mapped_to_init"
CLOUD_TOPIC = "/cloud_registered"
#: The log and the bag's odometry of one run agree to the log's 6 decimals; positions further
#: apart than this (m) mean they come from different runs.
LOG_BAG_TOLERANCE_M = 0.01


@dataclass(frozen=True)
class ImmeshSources:
    """The files an ImMesh import reads; each may be missing (None)."""

    mesh: Path | None
    log: Path | None
    bag: Path | None


@dataclass(frozen=True)
class ImmeshReport(CleanupReport):
    """What the import cleaned, where the mesh and trajectory came from (a file, plus the topic
    for a bag) and, when both a log and a bag were there, how far apart their positions were (m)."""

    mesh_from: str
    trajectory_from: str
    log_vs_bag_m: float | None


def find_immesh_sources(source: str | Path, bag: str | Path | None = None) -> ImmeshSources:
    """``rec_mesh.ply``, the log (in ``Log/`` or at the root) and the bag of an ImMesh output.

    Args:
        source: ImMesh's output folder, or a bag.
        bag: an explicit bag (default: ``source`` if it is a bag, else the one bag at its root).
    """
    source = Path(source)
    if bag is not None and not is_bag(Path(bag)):
        raise InputError("not a bag (.bag, .mcap or a rosbag2 folder)", path=bag, field="--bag")
    if is_bag(source):
        return ImmeshSources(None, None, Path(bag) if bag else source)
    if not source.is_dir():
        raise InputError("no such folder or bag", path=source)
    mesh = source / MESH_NAME
    logs = [log for log in (source / "Log" / LOG_NAME, source / LOG_NAME) if log.is_file()]
    return ImmeshSources(
        mesh if mesh.is_file() else None,
        logs[0] if logs else None,
        Path(bag) if bag else find_bag(source),
    )


def _to_lidar(trajectory: Trajectory, T_body_lidar: np.ndarray | None) -> Trajectory:
    """Body poses as LiDAR poses ``T_world_lidar = T_world_body · T_body_lidar`` (as is if None)."""
    if T_body_lidar is None:
        return trajectory
    return trajectory.transformed(T_right=np.asarray(T_body_lidar, dtype=np.float64))


def read_immesh_log(path: str | Path, T_body_lidar: np.ndarray | None = None) -> Trajectory:
    """ImMesh's trajectory log with the KITTI conjugation undone.

    Args:
        path: ``kitti_log_voxelmap.txt``.
        T_body_lidar: optional ``(4, 4)`` LiDAR→IMU extrinsic (ImMesh's ``extrinsic_T/R``) to
            return LiDAR poses ``T_world_lidar`` instead of the IMU (body) poses.

    Returns:
        Poses ``T_world_body`` (or ``T_world_lidar``) in ImMesh's world frame.
    """
    logged = read_tum(path)
    # ImMesh inverts T_lc as a general matrix (its rotation is not exactly orthonormal); so do we.
    poses = np.linalg.inv(T_LC) @ logged.poses @ T_LC
    # T_LC is orthonormal only to ~1e-6, so re-orthonormalise the rotations it touched.
    u, _, vt = np.linalg.svd(poses[:, :3, :3])
    poses[:, :3, :3] = u @ vt
    return _to_lidar(Trajectory.from_poses(logged.t_ns, poses, source=str(path)), T_body_lidar)


def log_vs_bag_m(log: Trajectory, log_path: Path, odometry: Trajectory, bag: Path) -> float:
    """The largest position difference (m) between the log and the bag's odometry over the log
    stamps the odometry covers. Raises :class:`InputError` when none is covered or they differ by
    more than :data:`LOG_BAG_TOLERANCE_M`: then they are not from the same run."""
    covered = odometry.covers(log.t_ns)
    remedy = "they are not from the same run; pass --bag with this run's bag, or move the bag away"
    if not covered.any():
        raise InputError(f"the odometry shares no time with {log_path}: {remedy}", path=bag)
    positions = odometry.interpolate(log.t_ns[covered])[:, :3, 3]
    worst = float(np.linalg.norm(positions - log.translations[covered], axis=1).max())
    if worst > LOG_BAG_TOLERANCE_M:
        raise InputError(
            f"the odometry and {log_path} differ by up to {worst:.3f} m "
            f"(at most {LOG_BAG_TOLERANCE_M} m expected): {remedy}",
            path=bag,
        )
    return worst


def import_immesh(
    source: str | Path,
    out_dir: str | Path,
    T_body_lidar: np.ndarray | None = None,
    bag: str | Path | None = None,
    odometry_topic: str = ODOMETRY_TOPIC,
    cloud_topic: str = CLOUD_TOPIC,
) -> ImmeshReport:
    """Import an ImMesh output folder (or bag) into ``out_dir/{mesh.ply, trajectory.tum}``.

    Trajectory: the bag's ``odometry_topic`` when there is a bag (checked against the log when
    that is there too), else the de-conjugated log. Mesh: ``rec_mesh.ply``, else the bag's
    ``cloud_topic`` meshed as a point map. The mesh is cleaned (unused vertices, degenerate and
    duplicate faces removed, orientation made consistent and facing the trajectory).

    Args:
        source: ImMesh's output folder, or a bag.
        T_body_lidar: optional ``(4, 4)`` LiDAR→IMU extrinsic (ImMesh's ``extrinsic_T/R``) to
            write LiDAR poses ``T_world_lidar`` instead of the IMU (body) poses.
        bag: the bag to read (default: ``source`` if it is one, else the one bag at its root).
    """
    found = find_immesh_sources(source, bag)
    if found.mesh is None and found.bag is None:
        raise InputError(
            f"no {MESH_NAME} (ImMesh writes it on 'Save Mesh') and no bag with {cloud_topic} to mesh",
            path=source,
        )
    if found.log is None and found.bag is None:
        raise InputError(f"no Log/{LOG_NAME} or {LOG_NAME}, and no bag with {odometry_topic}", path=source)
    log = read_immesh_log(found.log, T_body_lidar) if found.log else None
    agreement = None
    if found.bag is not None:
        trajectory = _to_lidar(read_odometry(found.bag, odometry_topic), T_body_lidar)
        trajectory_from = f"{found.bag} {odometry_topic}"
        agreement = log_vs_bag_m(log, found.log, trajectory, found.bag) if log is not None else None
    else:
        trajectory, trajectory_from = log, str(found.log)
    if found.mesh is not None:
        raw = load_mesh(found.mesh)
        mesh_from = str(found.mesh)
    else:
        raw = mesh_from_points(read_registered_points(found.bag, cloud_topic), trajectory.translations)
        mesh_from = f"{found.bag} {cloud_topic}"
    _, cleanup = write_slam_dir(out_dir, raw, trajectory)
    return ImmeshReport(
        **asdict(cleanup), mesh_from=mesh_from, trajectory_from=trajectory_from, log_vs_bag_m=agreement
    )
