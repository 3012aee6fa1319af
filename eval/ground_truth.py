"""Comparing a reconstruction with ground truth: a virtual-rig ground truth
(``lts sim OUT/ground_truth``) or a mesh already in the scene's frame (a survey of the site).

A reconstruction lives in its SLAM map frame; a virtual-rig ground truth in the simulator's world.
The two are related by the rigid transform that takes the keyframe camera poses onto the true
camera poses at the same stamps (:func:`~eval.trajectory_metrics.pose_alignment`, orientations
included, so a near-straight path does not leave a rotation free). A mesh file is used as it is.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property
from pathlib import Path

import numpy as np
import trimesh

from eval.geometry import (
    DEFAULT_SAMPLES,
    compare_point_sets,
    frustum_mask,
    metrics_from_distances,
    sample_distances,
    sample_surface,
    surface_distances,
    visible_mask,
)
from eval.trajectory_metrics import pose_alignment
from rig.errors import InputError
from rig.mesh_io import load_mesh
from rig.trajectory_io import read_tum
from slam_bridge.scene import Scene

GT_MESH = "mesh.ply"
GT_CAMERA_TRAJECTORY = "trajectory.tum"
#: Mesh files ``--gt`` takes as a ground truth in the scene's frame.
MESH_SUFFIXES = (".ply", ".obj", ".glb")


@dataclass(frozen=True)
class GroundTruth:
    """A ground-truth mesh in the reconstruction's world frame, and the alignment used.

    Attributes:
        mesh: the ground-truth mesh moved into the scene's world frame.
        T_gt_world: ``(4, 4)`` scene world → ground-truth world (z-up); the identity for a mesh
            file, whose frame is the scene's (a LiDAR map frame, z up).
        pose_rmse_m: RMS position difference of the aligned keyframe poses (how well they agree);
            ``None`` for a mesh file, which is not aligned.
    """

    mesh: trimesh.Trimesh
    T_gt_world: np.ndarray
    pose_rmse_m: float | None


def ground_truth_dir(path: str | Path) -> Path:
    """The folder holding ``mesh.ply`` and ``trajectory.tum``: ``path`` itself or its
    ``ground_truth/`` sub-folder (a simulation's output folder)."""
    path = Path(path)
    for candidate in (path, path / "ground_truth"):
        if (candidate / GT_MESH).is_file() and (candidate / GT_CAMERA_TRAJECTORY).is_file():
            return candidate
    raise InputError(
        f"expected a ground-truth folder with {GT_MESH} and {GT_CAMERA_TRAJECTORY} "
        "(lts sim OUT/ground_truth)",
        path=path,
    )


def ground_truth_mesh_file(path: str | Path) -> Path:
    """``path`` checked to be a mesh file ``--gt`` takes (its suffix; :func:`load_mesh` reads it)."""
    path = Path(path)
    if path.suffix.lower() not in MESH_SUFFIXES:
        kinds = "/".join(suffix[1:].upper() for suffix in MESH_SUFFIXES)
        raise InputError(
            f"expected a mesh file ({kinds}) in the scene's frame or a ground-truth folder "
            "(lts sim OUT/ground_truth)",
            path=path,
            field="--gt",
        )
    return path


def is_rig_ground_truth_mesh(path: Path) -> bool:
    """Whether ``path`` is the ``mesh.ply`` of a virtual-rig ground-truth folder (aligned as its
    folder is, not taken as already in the scene's frame)."""
    return path.name == GT_MESH and (path.parent / GT_CAMERA_TRAJECTORY).is_file()


def rig_ground_truth_dir(path: Path) -> Path | None:
    """The virtual-rig ground-truth folder ``path`` names (the folder, its parent or its own
    ``mesh.ply``; :func:`ground_truth_dir` checks it), or None for any other mesh file."""
    if path.is_file() and not is_rig_ground_truth_mesh(path):
        return None
    return ground_truth_dir(path.parent if path.is_file() else path)


def load_ground_truth(scene: Scene, path: str | Path) -> GroundTruth:
    """Load a ground truth in ``scene``'s world frame: a virtual-rig ground-truth folder (or its
    parent, or its own ``mesh.ply``) moved there by the keyframe poses, or any other mesh file
    (PLY/OBJ/GLB) as it is."""
    path = Path(path)
    folder = rig_ground_truth_dir(path)
    if folder is None:
        return GroundTruth(load_mesh(ground_truth_mesh_file(path)), np.eye(4), None)
    truth = read_tum(folder / GT_CAMERA_TRAJECTORY)
    stamps = np.array([k.t_ns for k in scene.keyframes], dtype=np.int64)
    covered = truth.covers(stamps)
    if covered.sum() < 3:
        raise InputError(
            f"covers {int(covered.sum())} of the scene's {len(stamps)} keyframe stamps; need 3 to align "
            "(is this the ground truth of the session the scene was prepared from?)",
            path=folder / GT_CAMERA_TRAJECTORY,
        )
    estimated = np.stack([k.T_world_cam for k in scene.keyframes])[covered]
    true_poses = truth.interpolate(stamps[covered])
    T_gt_world = pose_alignment(estimated, true_poses)
    aligned = np.einsum("ij,njk->nik", T_gt_world, estimated)[:, :3, 3]
    rmse = float(np.sqrt(np.mean(np.sum((aligned - true_poses[:, :3, 3]) ** 2, axis=1))))
    mesh = load_mesh(folder / GT_MESH).copy()
    mesh.apply_transform(np.linalg.inv(T_gt_world))
    return GroundTruth(mesh, T_gt_world, rmse)


@dataclass(frozen=True)
class CulledSamples:
    """Area-uniform samples of a reconstruction and of the ground truth inside the training
    cameras' frusta, and which ground-truth samples some training camera actually sees.

    Attributes:
        reconstructed: ``(N, 3)`` reconstruction samples in the frusta.
        ground_truth: ``(M, 3)`` ground-truth samples in the frusta.
        visible: ``(M,)`` bool, not hidden from every training camera by other ground truth.
    """

    reconstructed: np.ndarray
    ground_truth: np.ndarray
    visible: np.ndarray

    @cached_property
    def distances(self) -> tuple[np.ndarray, np.ndarray]:
        """Each reconstruction sample's distance to the nearest ground-truth sample ``(N,)`` and
        back ``(M,)`` (:func:`~eval.geometry.sample_distances`), found once for the metrics and
        the report's pictures."""
        return sample_distances(self.reconstructed, self.ground_truth)


def culled_samples(
    reconstructed: trimesh.Trimesh,
    scene: Scene,
    truth: GroundTruth,
    samples: int = DEFAULT_SAMPLES,
    far_m: float = np.inf,
) -> CulledSamples:
    """Sample both meshes (seeds 0 and 1) and cull them to the union of the training frusta."""
    poses = np.stack([k.T_world_cam for k in scene.split("train")])
    rec_points = sample_surface(reconstructed, samples, seed=0)
    gt_points = sample_surface(truth.mesh, samples, seed=1)
    rec_points = rec_points[frustum_mask(rec_points, poses, scene.camera, far=far_m)]
    gt_points = gt_points[frustum_mask(gt_points, poses, scene.camera, far=far_m)]
    visible = visible_mask(gt_points, truth.mesh, poses, scene.camera, max_range_m=far_m)
    return CulledSamples(rec_points, gt_points, visible)


def compare_culled_surfaces(
    points: CulledSamples, reconstructed: trimesh.Trimesh, truth: GroundTruth, threshold_m: float = 0.1
) -> dict[str, float]:
    """The metrics of :func:`compare_culled` with each sample's distance to the other *surface*
    (point to mesh) instead of to the other mesh's nearest sample: ``chamfer_surface_m``,
    ``fscore_surface``, ... and ``chamfer_visible_surface_m``, ``fscore_visible_surface``, ...

    Sample to sample, a sample on the true surface is as far from the nearest other sample as
    the samples are apart, and with a fixed count that grows with the scene: 200 000 samples
    of the virtual street's 34 000 m² lie ~0.4 m apart, so a mesh 87 % within 10 cm of the
    street scores a precision of 0.13 (0.77 surface to surface); in the room (~130 m², ~3 cm
    apart) the two differ by about 0.01 in F and 1.3 cm in Chamfer."""
    to_gt = surface_distances(points.reconstructed, truth.mesh)
    to_rec = surface_distances(points.ground_truth, reconstructed)
    frustum = metrics_from_distances(to_gt, to_rec, threshold_m)
    visible = metrics_from_distances(to_gt, to_rec[points.visible], threshold_m)
    return {**frustum.named("surface"), **visible.named("visible_surface")}


def compare_culled(points: CulledSamples, threshold_m: float = 0.1) -> dict[str, float]:
    """Geometric metrics of culled samples (the culled-mesh protocol of the Replica evaluations:
    surfaces no training camera saw count neither for nor against a method): ``chamfer_m``,
    ``fscore``, ... against the ground truth in the frusta, the same as ``chamfer_visible_m``,
    ``fscore_visible``, ... against the ground truth some training camera sees (the back of a box
    is in the frusta but no image shows it), and ``gt_visible_fraction``."""
    frustum = metrics_from_distances(*points.distances, threshold_m)
    visible = compare_point_sets(points.reconstructed, points.ground_truth[points.visible], threshold_m)
    return {
        **frustum.named(),
        **visible.named("visible"),
        "gt_visible_fraction": float(points.visible.mean()),
    }
