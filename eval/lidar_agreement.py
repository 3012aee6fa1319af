"""Geometry without ground truth: the exported mesh against the LiDAR returns of the held-out
keyframes (pseudo ground truth, as real-world reconstruction papers score a drive).

Training never sees a test keyframe's image or its LiDAR depth, so its returns judge the mesh
where the cameras were not trained. For each test keyframe's returns (the ones its camera sees,
one per pixel, in the world frame):

- *recall*: the share of returns within ``threshold_m`` of the mesh (the mesh is where the LiDAR
  says a surface is);
- *precision*: along each return's pixel ray, the mesh surface the camera sees, and the share of
  those hits within ``threshold_m`` of a return of that view (the mesh puts no surface where the
  LiDAR saw something else); rays that miss the mesh count only against recall;
- the F-score of the two, and the median distance of the returns to the mesh.

The warm-start mesh of a fallback-mapper run was built from every sweep, test frames' included, so
this is a check of what training made of the geometry, not a fully independent ground truth.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import trimesh
from scipy.spatial import cKDTree

from rig.mesh_rays import cast_camera_rays, mesh_raycaster
from rig.transforms import transform_points
from slam_bridge.scene import Keyframe, Scene

#: Real-world papers score drives at 20 cm (LiDAR noise and sparsity at tens of metres).
LIDAR_THRESHOLD_M = 0.2


@dataclass(frozen=True)
class LidarAgreement:
    """The scores of :func:`lidar_agreement`; ``points`` returns over ``views`` test keyframes."""

    precision: float
    recall: float
    fscore: float
    distance_median_m: float
    threshold_m: float
    points: int
    views: int

    def metrics(self) -> dict[str, float | int]:
        """The ``lidar_*`` fields of ``eval.json``."""
        return {
            "lidar_fscore": self.fscore,
            "lidar_precision": self.precision,
            "lidar_recall": self.recall,
            "lidar_distance_median_m": self.distance_median_m,
            "lidar_threshold_m": self.threshold_m,
            "lidar_points": self.points,
        }


def lidar_agreement(
    mesh: trimesh.Trimesh, scene: Scene, keyframes: list[Keyframe], threshold_m: float = LIDAR_THRESHOLD_M
) -> LidarAgreement | None:
    """Precision, recall and F-score of ``mesh`` against the LiDAR returns of ``keyframes`` (see
    the module docstring); None when those keyframes have no returns."""
    from rig.open3d_lite import o3d

    caster = mesh_raycaster(mesh)
    width = scene.camera.width
    to_mesh, to_returns = [], []
    views = 0
    for keyframe in keyframes:
        lidar = scene.lidar(keyframe)
        if not len(lidar.points):
            continue
        views += 1
        returns = transform_points(keyframe.T_world_cam, lidar.points.astype(np.float64))
        to_mesh.append(caster.compute_distance(o3d.core.Tensor(returns.astype(np.float32))).numpy())
        rows, cols = np.divmod(lidar.pixels, width)
        rays = scene.camera.unproject(np.column_stack([cols, rows]).astype(np.float64))
        rays /= np.linalg.norm(rays, axis=1, keepdims=True)
        t_hit = cast_camera_rays(caster, keyframe.T_world_cam, rays)["t_hit"]
        seen = np.isfinite(t_hit)
        hits = keyframe.T_world_cam[:3, 3] + t_hit[seen, None] * (rays[seen] @ keyframe.T_world_cam[:3, :3].T)
        to_returns.append(cKDTree(returns).query(hits)[0] if len(hits) else np.zeros(0))
    if not to_mesh:
        return None
    mesh_d, return_d = np.concatenate(to_mesh), np.concatenate(to_returns)
    recall = float(np.mean(mesh_d <= threshold_m))
    precision = float(np.mean(return_d <= threshold_m)) if return_d.size else 0.0
    fscore = 2 * precision * recall / (precision + recall) if precision + recall > 0 else 0.0
    return LidarAgreement(
        precision, recall, fscore, float(np.median(mesh_d)), float(threshold_m), int(mesh_d.size), views
    )
