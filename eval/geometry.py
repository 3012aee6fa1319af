"""Geometric accuracy of a reconstructed mesh against ground truth.

The protocol of the mesh-reconstruction literature: sample points uniformly by area on both
meshes, optionally cull the ground truth to the union of the training cameras' frusta, then
accuracy (rec → GT mean distance), completeness (GT → rec), Chamfer-L1 (their mean), and
precision / recall / F-score at a distance threshold (10 cm synthetic, 20 cm real).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import asdict, dataclass

import numpy as np
import trimesh
from scipy.spatial import cKDTree

from rig.camera import CameraModel
from rig.errors import InputError
from rig.mesh_rays import mesh_raycaster
from rig.transforms import invert, transform_points

DEFAULT_SAMPLES = 200_000


@dataclass(frozen=True)
class GeometricMetrics:
    """Distances in metres; precision/recall/F-score in [0, 1]."""

    accuracy_m: float
    completeness_m: float
    chamfer_m: float
    precision: float
    recall: float
    fscore: float
    threshold_m: float

    def to_dict(self) -> dict[str, float]:
        return asdict(self)

    def named(self, variant: str = "") -> dict[str, float]:
        """The metrics without the threshold, ``variant`` put into each name before its unit
        (``chamfer_m`` → ``chamfer_visible_m``, ``fscore`` → ``fscore_visible``)."""
        values = self.to_dict()
        del values["threshold_m"]
        if not variant:
            return values
        return {
            (f"{name[:-2]}_{variant}_m" if name.endswith("_m") else f"{name}_{variant}"): value
            for name, value in values.items()
        }


def sample_surface(mesh: trimesh.Trimesh, count: int = DEFAULT_SAMPLES, seed: int = 0) -> np.ndarray:
    """``(count, 3)`` points uniformly distributed by area over the mesh surface (seeded).

    Raises:
        InputError: ``count`` < 1, vertices that are not finite, or no surface area.
    """
    if int(count) < 1:
        raise InputError(f"need at least one sample, got {count}", field="samples")
    if not np.all(np.isfinite(mesh.vertices)):
        raise InputError("mesh vertices hold NaN or Inf", field="vertices")
    if not mesh.area > 0:  # also an empty mesh (area 0)
        raise InputError("mesh has zero surface area", field="faces")
    points, _ = trimesh.sample.sample_surface(mesh, count, seed=seed)
    return np.asarray(points, dtype=np.float64)


def surface_distances(points: np.ndarray, mesh: trimesh.Trimesh) -> np.ndarray:
    """Distance (m) from each point ``(N, 3)`` to the nearest point of ``mesh``'s surface ``(N,)``
    (open3d's closest-point query, float32 precision)."""
    from rig.open3d_lite import o3d

    query = o3d.core.Tensor(np.asarray(points, dtype=np.float32))
    return mesh_raycaster(mesh).compute_distance(query).numpy().astype(np.float64)


def frustum_mask(
    points: np.ndarray,
    poses_world_cam: np.ndarray,
    camera: CameraModel,
    near: float = 0.05,
    far: float = np.inf,
) -> np.ndarray:
    """Boolean ``(N,)``: which world points ``(N, 3)`` fall inside at least one camera's frustum.

    Args:
        poses_world_cam: ``(K, 4, 4)`` camera-to-world poses ``T_world_cam``.
        camera: intrinsics; the frustum is the image rectangle between ``near`` and ``far``.
    """
    points = np.asarray(points, dtype=np.float64)
    inside = np.zeros(len(points), dtype=bool)
    for T_cam_world in invert(np.asarray(poses_world_cam)):
        p = transform_points(T_cam_world, points)
        depth_ok = (p[:, 2] > near) & (p[:, 2] < far) & ~inside
        if depth_ok.any():
            candidates = np.flatnonzero(depth_ok)
            inside[candidates[camera.in_image(camera.project(p[candidates]))]] = True
    return inside


def visible_mask(
    points: np.ndarray,
    mesh: trimesh.Trimesh,
    poses_world_cam: np.ndarray,
    camera: CameraModel,
    tolerance_m: float = 0.02,
    max_range_m: float = np.inf,
) -> np.ndarray:
    """Boolean ``(N,)``: which surface points ``(N, 3)`` of ``mesh`` at least one camera sees —
    inside its frustum and not hidden behind another part of ``mesh`` (a ray cast from the camera
    reaches within ``tolerance_m`` of the point)."""
    from rig.open3d_lite import o3d

    scene = mesh_raycaster(mesh)
    points = np.asarray(points, dtype=np.float64)
    seen = np.zeros(len(points), dtype=bool)
    for pose in np.asarray(poses_world_cam):
        candidates = np.flatnonzero(~seen & frustum_mask(points, pose[None], camera, far=max_range_m))
        if len(candidates) == 0:
            continue
        offset = points[candidates] - pose[:3, 3]
        distance = np.linalg.norm(offset, axis=1)
        rays = np.hstack([np.broadcast_to(pose[:3, 3], offset.shape), offset / distance[:, None]])
        t_hit = scene.cast_rays(o3d.core.Tensor(rays.astype(np.float32)))["t_hit"].numpy()
        seen[candidates[t_hit >= distance - tolerance_m]] = True
    return seen


def compare_point_sets(
    reconstructed: np.ndarray, ground_truth: np.ndarray, threshold_m: float
) -> GeometricMetrics:
    """Accuracy, completeness, Chamfer-L1 and precision/recall/F-score of two point sets ``(N, 3)``.

    Raises:
        InputError: either set is empty (a metric of nothing would be a confident wrong number),
            holds NaN/Inf or is not ``(N, 3)``, or the threshold is not a positive number.
    """
    if not (np.isfinite(threshold_m) and threshold_m > 0):
        raise InputError(
            f"threshold must be a positive number of metres, got {threshold_m}", field="threshold_m"
        )
    reconstructed = np.asarray(reconstructed, dtype=np.float64)
    ground_truth = np.asarray(ground_truth, dtype=np.float64)
    if reconstructed.size == 0:
        raise InputError("reconstruction has no points to compare", field="reconstructed")
    if ground_truth.size == 0:
        raise InputError("ground truth has no points to compare (culled away?)", field="ground_truth")
    for name, points in (("reconstructed", reconstructed), ("ground_truth", ground_truth)):
        if points.ndim != 2 or points.shape[1] != 3:
            raise InputError(f"expected points of shape (N, 3), got {points.shape}", field=name)
        if not np.all(np.isfinite(points)):
            raise InputError("points hold NaN or Inf", field=name)
    return metrics_from_distances(*sample_distances(reconstructed, ground_truth), threshold_m)


def sample_distances(reconstructed: np.ndarray, ground_truth: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Each reconstruction sample's distance to the nearest ground-truth sample ``(N,)`` and each
    ground-truth sample's to the nearest reconstruction sample ``(M,)``."""
    to_gt, _ = cKDTree(ground_truth).query(reconstructed, workers=-1)
    to_rec, _ = cKDTree(reconstructed).query(ground_truth, workers=-1)
    return to_gt, to_rec


def metrics_from_distances(to_gt: np.ndarray, to_rec: np.ndarray, threshold_m: float) -> GeometricMetrics:
    """The metrics of distances (m) from reconstruction samples to the ground truth ``(N,)`` and
    from ground-truth samples to the reconstruction ``(M,)``.

    Raises:
        InputError: either is empty.
    """
    if len(to_gt) == 0:
        raise InputError("reconstruction has no points to compare", field="reconstructed")
    if len(to_rec) == 0:
        raise InputError("ground truth has no points to compare (culled away?)", field="ground_truth")
    precision = float(np.mean(to_gt < threshold_m))
    recall = float(np.mean(to_rec < threshold_m))
    fscore = 0.0 if precision + recall == 0 else 2 * precision * recall / (precision + recall)
    accuracy, completeness = float(to_gt.mean()), float(to_rec.mean())
    return GeometricMetrics(
        accuracy_m=accuracy,
        completeness_m=completeness,
        chamfer_m=(accuracy + completeness) / 2,
        precision=precision,
        recall=recall,
        fscore=fscore,
        threshold_m=float(threshold_m),
    )


def compare_meshes(
    reconstructed: trimesh.Trimesh,
    ground_truth: trimesh.Trimesh,
    threshold_m: float = 0.1,
    samples: int = DEFAULT_SAMPLES,
    seed: int = 0,
    gt_mask_fn: Callable[[np.ndarray], np.ndarray] | None = None,
) -> GeometricMetrics:
    """Sample both meshes and compare them (see :func:`compare_point_sets`).

    ``gt_mask_fn`` optionally maps GT sample points ``(N, 3)`` to a keep-mask ``(N,)`` — e.g. a
    :func:`frustum_mask` closure — to cull ground truth the cameras never saw.
    """
    rec_points = sample_surface(reconstructed, samples, seed)
    gt_points = sample_surface(ground_truth, samples, seed + 1)
    if gt_mask_fn is not None:
        gt_points = gt_points[gt_mask_fn(gt_points)]
    return compare_point_sets(rec_points, gt_points, threshold_m)
