"""The mesh against the held-out keyframes' LiDAR returns: the true surface agrees, a displaced or
a half-missing one does not, in the way precision and recall say."""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pytest
import trimesh

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "splat"))
from training_scene import corner_mesh, write_training_scene

from eval.lidar_agreement import lidar_agreement
from slam_bridge.scene import Scene, load_scene


@pytest.fixture(scope="module")
def scene(tmp_path_factory: pytest.TempPathFactory) -> Scene:
    return load_scene(write_training_scene(tmp_path_factory.mktemp("corner")))


def test_the_true_surface_agrees_with_the_returns(scene: Scene) -> None:
    result = lidar_agreement(corner_mesh(16), scene, scene.split("test"))
    assert result is not None and result.views == 1 and result.points > 500
    assert result.precision > 0.99 and result.recall > 0.99 and result.fscore > 0.99
    assert result.distance_median_m < 0.01


def test_a_displaced_surface_fails_both(scene: Scene) -> None:
    moved = corner_mesh(16).apply_translation([0.0, -0.5, 0.3])  # wall 50 cm nearer, floor 30 cm up
    result = lidar_agreement(moved, scene, scene.split("test"))
    assert result.precision < 0.1 and result.recall < 0.1 and result.distance_median_m > 0.25


def test_a_missing_wall_costs_recall_not_precision(scene: Scene) -> None:
    full = corner_mesh(16)
    floor = full.faces[np.asarray(full.vertices)[full.faces][:, :, 2].max(axis=1) < 1e-9]
    result = lidar_agreement(trimesh.Trimesh(full.vertices, floor, process=False), scene, scene.split("test"))
    assert result.precision > 0.99 and result.recall < 0.9
    assert result.metrics()["lidar_fscore"] == pytest.approx(
        2 * result.precision * result.recall / (result.precision + result.recall)
    )
