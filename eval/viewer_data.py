"""What ``lts view`` shows, read from a run folder: the scene, the model, the exported mesh and,
with ``--gt``, the ground truth in the scene frame with the mesh's distance to it.

A run folder is a training run (``lts train --out``: ``run.json``, ``model.pt``, ``mesh.ply``) or
the output folder of ``lts reconstruct``, whose training run is its ``train/`` sub-folder.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import trimesh
from scipy.spatial import cKDTree

from eval.geometry import compare_point_sets, frustum_mask, sample_surface
from eval.ground_truth import load_ground_truth
from eval.run_inputs import resolve_gt, resolve_run_dir
from rig.errors import InputError
from rig.mesh_io import load_mesh
from slam_bridge.scene import Scene, load_scene
from splat import run_dir as layout
from splat.model import TriangleModel, load_model

MESH_FILE = "mesh.ply"
#: Up axis of a virtual-rig ground-truth world (its scenes are z-up).
GT_UP = np.array([0.0, 0.0, 1.0])


@dataclass(frozen=True)
class TruthView:
    """The ground truth as the viewer shows it.

    Attributes:
        mesh: the ground-truth mesh in the scene frame.
        aligned: whether it was moved there through its camera trajectory (``False``: a mesh
            file taken as already in the scene frame).
        up: ``(3,)`` unit up axis of the scene frame, or ``None`` when unknown.
        mesh_distance: ``(V,)`` distance in metres of each vertex of the run's mesh to the truth.
        fscore: F-score of the run's mesh at ``threshold_m``, both meshes culled to the training
            frusta (the ``fscore`` of ``lts eval``).
        threshold_m: the F-score's distance threshold.
    """

    mesh: trimesh.Trimesh
    aligned: bool
    up: np.ndarray | None
    mesh_distance: np.ndarray
    fscore: float
    threshold_m: float


@dataclass(frozen=True)
class ViewerData:
    """A run ready to show: ``mesh`` is the exported ``mesh.ply`` (``None`` if the run has none)."""

    run_dir: Path
    scene: Scene
    model: TriangleModel
    mesh: trimesh.Trimesh | None
    truth: TruthView | None

    @property
    def up(self) -> np.ndarray:
        """``(3,)`` unit up axis of the scene frame: the ground truth's when known, else the mean
        of the keyframe cameras' up (``-y``) axes."""
        if self.truth is not None and self.truth.up is not None:
            return self.truth.up
        up = -np.mean([k.T_world_cam[:3, 1] for k in self.scene.keyframes], axis=0)
        norm = np.linalg.norm(up)
        return up / norm if norm > 1e-6 else GT_UP


def mesh_vertex_distance(mesh: trimesh.Trimesh, truth: trimesh.Trimesh, samples: int) -> np.ndarray:
    """``(V,)`` distance of each vertex of ``mesh`` to ``truth``, approximated by the nearest of
    ``samples`` area-uniform points on ``truth`` (seed 1)."""
    points = sample_surface(truth, samples, seed=1)
    distance, _ = cKDTree(points).query(np.asarray(mesh.vertices), workers=-1)
    return distance


def culled_fscore(
    mesh: trimesh.Trimesh, truth: trimesh.Trimesh, scene: Scene, threshold_m: float, samples: int
) -> float:
    """F-score of ``mesh`` against ``truth`` at ``threshold_m``: ``samples`` points on each (seeds
    0 and 1) culled to the training cameras' frusta, as ``lts eval`` culls them."""
    poses = np.stack([k.T_world_cam for k in scene.split("train") or scene.keyframes])
    rec = sample_surface(mesh, samples, seed=0)
    gt = sample_surface(truth, samples, seed=1)
    rec = rec[frustum_mask(rec, poses, scene.camera)]
    gt = gt[frustum_mask(gt, poses, scene.camera)]
    return compare_point_sets(rec, gt, threshold_m).fscore


def load_truth(scene: Scene, gt: str | Path) -> tuple[trimesh.Trimesh, bool, np.ndarray | None]:
    """The ground truth ``gt`` names (see :mod:`eval.run_inputs`), in ``scene``'s frame:
    ``(mesh, aligned, up)``; a virtual-rig ground truth is aligned through its trajectory (up =
    the truth's z), any other mesh file is taken as already in the scene frame (up unknown).

    Raises:
        InputError: ``gt`` is missing, unreadable or cannot be aligned.
    """
    resolved = resolve_gt(gt)
    truth = load_ground_truth(scene, resolved)
    if not resolved.is_dir():
        return truth.mesh, False, None
    up = truth.T_gt_world[:3, :3].T @ GT_UP
    return truth.mesh, True, up / np.linalg.norm(up)


def load_viewer_data(
    run: str | Path,
    gt: str | Path | None = None,
    device: str = "cpu",
    threshold_m: float = 0.1,
    samples: int = 100_000,
    log: Callable[[str], None] = lambda _: None,
) -> ViewerData:
    """Read the run ``run`` names (see :mod:`eval.run_inputs`) and, with ``gt``, its ground truth
    (see :func:`load_truth`) with the distances and the F-score of the run's mesh at
    ``threshold_m`` (``samples`` surface points per mesh)."""
    run_dir = resolve_run_dir(run)
    scene = load_scene(layout.scene_of(run_dir))
    model = load_model(layout.model_path(run_dir), device)
    mesh_path = run_dir / MESH_FILE
    mesh = load_mesh(mesh_path) if mesh_path.is_file() else None
    truth = None
    if gt is not None:
        truth_mesh, aligned, up = load_truth(scene, gt)
        if mesh is None:
            raise InputError(f"--gt needs the run's exported mesh ({MESH_FILE})", path=run_dir)
        log(f"comparing {MESH_FILE} with the ground truth ({samples} samples each)")
        distance = mesh_vertex_distance(mesh, truth_mesh, samples)
        fscore = culled_fscore(mesh, truth_mesh, scene, threshold_m, samples)
        truth = TruthView(truth_mesh, aligned, up, distance, fscore, threshold_m)
    return ViewerData(run_dir, scene, model, mesh, truth)
