"""Pixels of moving objects from a virtual-rig ground truth: a cube that drives in front of a wall."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import trimesh

from eval.moving_pixels import mover_names, moving_pixel_masks
from rig.camera import CameraModel
from rig.trajectory import Trajectory
from rig.trajectory_io import write_tum

CAMERA = CameraModel("pinhole", 64, 48, [[40, 0, 31.5], [0, 40, 23.5], [0, 0, 1]], [])
STAMPS = np.array([0, 1_000_000_000], dtype=np.int64)


def _translation(x: float, y: float, z: float) -> np.ndarray:
    T = np.eye(4)
    T[:3, 3] = x, y, z
    return T


def _ground_truth(root: Path, mover_z: float) -> Path:
    """A wall 10 m ahead of a camera at the origin (looking along +z); a 2 m cube ``mover_z`` ahead
    that moves 20 m sideways (out of view) between the two stamps."""
    gt = root / "ground_truth"
    (gt / "movers").mkdir(parents=True)
    trimesh.creation.box(extents=(100, 100, 0.1), transform=_translation(0, 0, 10)).export(gt / "mesh.ply")
    write_tum(Trajectory.from_poses(STAMPS, np.stack([np.eye(4)] * 2)), gt / "trajectory.tum")
    trimesh.creation.box(extents=(2, 2, 2)).export(gt / "movers" / "cube.ply")
    poses = np.stack([_translation(0, 0, mover_z), _translation(20, 0, mover_z)])
    write_tum(Trajectory.from_poses(STAMPS, poses), gt / "movers" / "cube.tum")
    return gt


def test_the_pixels_of_a_mover_in_front_of_the_scene_are_masked(tmp_path: Path) -> None:
    gt = _ground_truth(tmp_path, mover_z=5.0)
    assert mover_names(gt) == ["cube"]
    masks = moving_pixel_masks(gt, CAMERA, STAMPS)
    assert [m.shape for m in masks] == [(48, 64)] * 2
    # The cube's front face (z = 4) spans ±1 m: ±10 px around the centre, widened by 2 px.
    rows, cols = np.nonzero(masks[0])
    assert masks[0].sum() >= 300 and abs(cols.mean() - 31.5) < 1 and abs(rows.mean() - 23.5) < 1
    assert cols.min() >= 31.5 - 13 and cols.max() <= 31.5 + 13
    assert not masks[1].any()  # driven out of view


def test_a_mover_behind_the_static_scene_masks_nothing(tmp_path: Path) -> None:
    gt = _ground_truth(tmp_path, mover_z=15.0)
    assert not moving_pixel_masks(gt, CAMERA, STAMPS[:1])[0].any()


def test_a_ground_truth_without_movers_has_none(tmp_path: Path) -> None:
    assert mover_names(tmp_path) == []


def test_mesh_area_inside_a_movers_swept_volume(tmp_path: Path) -> None:
    """Of two equal squares, one lies inside the cube at its first pose: half the area is a ghost,
    counted in the ground truth's world after the scene-to-truth transform."""
    from eval.mover_ghosts import swept_area_fraction

    gt = _ground_truth(tmp_path, mover_z=5.0)
    square = trimesh.Trimesh(
        [[-0.5, -0.5, 0], [0.5, -0.5, 0], [0.5, 0.5, 0], [-0.5, 0.5, 0]], [[0, 1, 2], [0, 2, 3]]
    )
    scene_to_gt = _translation(0, 0, 5)  # the scene's origin is the cube's first centre
    mesh = trimesh.util.concatenate([square, square.copy().apply_translation([10, 0, 0])])
    assert abs(swept_area_fraction(mesh, scene_to_gt, gt, 4000) - 0.5) < 0.05
    assert swept_area_fraction(square, np.eye(4), gt, 1000) == 0.0  # at z = 0: in front of the cube
