"""Import of ImMesh output (hku-mars/ImMesh) into a SLAM folder.

ImMesh writes, when the user presses "Save Mesh":

- ``rec_mesh.ply``: binary PLY written by PCL, xyz only; its vertex list holds every map point,
  including points no face uses, and faces may be flipped.
- ``Log/kitti_log_voxelmap.txt``: TUM-like lines ``t tx ty tz qx qy qz qw`` (6 decimals) of the
  body (IMU) pose ``T_world_body`` in ImMesh's ``camera_init`` world frame — but each pose was
  conjugated before writing, ``T_log = T_lc · T · T_lc⁻¹``, with the hard-coded KITTI
  velodyne→camera matrix :data:`T_LC` (ImMesh ``src/voxel_mapping_common.cpp``, ``kitti_log``).
  We undo it: ``T = T_lc⁻¹ · T_log · T_lc``.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from rig.errors import InputError
from rig.mesh_io import load_mesh
from rig.trajectory import Trajectory
from rig.trajectory_io import read_tum
from slam_bridge.mesh_cleanup import CleanupReport, clean_mesh
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


def find_immesh_files(folder: str | Path) -> tuple[Path, Path]:
    """``(rec_mesh.ply, kitti_log_voxelmap.txt)`` in an ImMesh output folder (log in ``Log/`` or
    at the root)."""
    folder = Path(folder)
    mesh = folder / MESH_NAME
    if not mesh.is_file():
        raise InputError(f"no {MESH_NAME} (ImMesh writes it on 'Save Mesh')", path=folder)
    for log in (folder / "Log" / LOG_NAME, folder / LOG_NAME):
        if log.is_file():
            return mesh, log
    raise InputError(f"no Log/{LOG_NAME} or {LOG_NAME}", path=folder)


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
    if T_body_lidar is not None:
        poses = poses @ np.asarray(T_body_lidar, dtype=np.float64)
    # T_LC is orthonormal only to ~1e-6, so re-orthonormalise the rotations it touched.
    u, _, vt = np.linalg.svd(poses[:, :3, :3])
    poses[:, :3, :3] = u @ vt
    return Trajectory.from_poses(logged.t_ns, poses, source=str(path))


def import_immesh(
    folder: str | Path, out_dir: str | Path, T_body_lidar: np.ndarray | None = None
) -> CleanupReport:
    """Import an ImMesh output folder into ``out_dir/{mesh.ply, trajectory.tum}``.

    The mesh is cleaned (unused vertices, degenerate and duplicate faces removed, orientation made
    consistent and facing the trajectory); the trajectory is de-conjugated.
    """
    mesh_path, log_path = find_immesh_files(folder)
    trajectory = read_immesh_log(log_path, T_body_lidar)
    raw = load_mesh(mesh_path)
    mesh, report = clean_mesh(raw.vertices, raw.faces, viewpoints=trajectory.translations)
    write_slam_dir(out_dir, mesh, trajectory)
    return report
