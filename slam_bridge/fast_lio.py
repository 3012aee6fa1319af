"""Import of FAST-LIO output: the saved point map (``scans.pcd``) and the odometry topic.

FAST-LIO keeps no mesh, so one is made here from the map by screened Poisson reconstruction
(open3d), with normals oriented towards the trajectory and the surface trimmed to where points
are. Poses are FAST-LIO's body (IMU) poses in its ``camera_init`` world frame.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import trimesh
from scipy.spatial import cKDTree

from calib.pointcloud_io import read_point_cloud
from rig.errors import InputError
from rig.session.foreign import read_foreign_trajectory
from rig.trajectory import Trajectory
from rig.trajectory_io import read_trajectory
from slam_bridge.mesh_cleanup import CleanupReport, clean_mesh
from slam_bridge.slam_dir import write_slam_dir

ODOMETRY_TOPIC = "/Odometry"
BAG_SUFFIXES = (".bag", ".mcap", ".db3")


def mesh_from_points(
    points: np.ndarray, viewpoints: np.ndarray, voxel_m: float = 0.03, depth: int = 9
) -> trimesh.Trimesh:
    """Surface mesh of a point map ``(N, 3)`` seen from ``viewpoints`` ``(P, 3)``.

    Normals are estimated from neighbours and flipped to face the nearest viewpoint; Poisson's
    surface is kept only within ``3 * voxel_m`` of a map point (it closes holes elsewhere).
    """
    import open3d as o3d

    if len(points) < 100:
        raise InputError(f"the point map holds only {len(points)} points", field="points")
    cloud = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(np.asarray(points, dtype=np.float64)))
    cloud = cloud.voxel_down_sample(voxel_m)
    cloud.estimate_normals(o3d.geometry.KDTreeSearchParamHybrid(radius=4 * voxel_m, max_nn=30))
    positions = np.asarray(cloud.points)
    normals = np.asarray(cloud.normals)
    _, nearest = cKDTree(viewpoints).query(positions)
    flip = np.einsum("ij,ij->i", normals, viewpoints[nearest] - positions) < 0
    normals[flip] *= -1
    cloud.normals = o3d.utility.Vector3dVector(normals)
    surface, _ = o3d.geometry.TriangleMesh.create_from_point_cloud_poisson(cloud, depth=depth)
    vertices = np.asarray(surface.vertices)
    distance, _ = cKDTree(positions).query(vertices)
    surface.remove_vertices_by_mask(distance > 3 * voxel_m)
    return trimesh.Trimesh(np.asarray(surface.vertices), np.asarray(surface.triangles), process=False)


def _find_map(folder: Path) -> Path:
    for candidate in (folder / "scans.pcd", folder / "PCD" / "scans.pcd"):
        if candidate.is_file():
            return candidate
    raise InputError("no scans.pcd or PCD/scans.pcd (FAST-LIO saves it with pcd_save_en)", path=folder)


def _find_trajectory(folder: Path, topic: str) -> Trajectory:
    bags = sorted(p for p in folder.iterdir() if p.suffix in BAG_SUFFIXES or (p / "metadata.yaml").is_file())
    if len(bags) != 1:
        raise InputError(
            f"expected one bag with the odometry topic in the folder, found {len(bags)}; pass --trajectory",
            path=folder,
        )
    return read_foreign_trajectory(bags[0], topic)


def import_fast_lio(
    folder: str | Path,
    out_dir: str | Path,
    trajectory_path: str | Path | None = None,
    odometry_topic: str = ODOMETRY_TOPIC,
) -> CleanupReport:
    """Import FAST-LIO's map and odometry into ``out_dir/{mesh.ply, trajectory.tum}``.

    The odometry comes from ``trajectory_path`` (any trajectory file) or from the one bag in
    ``folder`` (topic ``odometry_topic``, nav_msgs/Odometry).
    """
    folder = Path(folder)
    trajectory = (
        read_trajectory(trajectory_path) if trajectory_path else _find_trajectory(folder, odometry_topic)
    )
    cloud = read_point_cloud(_find_map(folder))
    raw = mesh_from_points(cloud.points, trajectory.translations)
    mesh, report = clean_mesh(raw.vertices, raw.faces, viewpoints=trajectory.translations)
    write_slam_dir(out_dir, mesh, trajectory)
    return report
