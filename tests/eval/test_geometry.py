import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import trimesh

from eval.geometry import (
    compare_meshes,
    compare_point_sets,
    frustum_mask,
    metrics_from_distances,
    sample_surface,
    surface_distances,
)
from rig import CameraModel, InputError, make_transform


def plane(x0: float, x1: float, z: float = 0.0) -> trimesh.Trimesh:
    """An axis-aligned rectangle [x0, x1] × [0, 1] at height z (two triangles)."""
    vertices = np.array([[x0, 0, z], [x1, 0, z], [x1, 1, z], [x0, 1, z]], dtype=float)
    return trimesh.Trimesh(vertices, [[0, 1, 2], [0, 2, 3]], process=False)


def test_plane_against_the_same_plane_shifted_5cm() -> None:
    a, b = plane(0, 1), plane(0, 1, z=0.05)
    at_10cm = compare_meshes(a, b, threshold_m=0.10, samples=20_000)
    assert at_10cm.fscore == 1.0 and at_10cm.precision == 1.0 and at_10cm.recall == 1.0
    assert at_10cm.chamfer_m == pytest.approx(0.05, abs=1e-3)
    at_2cm = compare_meshes(a, b, threshold_m=0.02, samples=20_000)
    assert at_2cm.fscore == 0.0


def test_half_overlapping_meshes() -> None:
    # [0, 1] against [0.5, 1.5]: half of each lies on the other; the rest is 0..0.5 m away laterally.
    metrics = compare_meshes(plane(0, 1), plane(0.5, 1.5), threshold_m=0.1, samples=40_000)
    assert metrics.precision == pytest.approx(0.6, abs=0.01)  # 0.5 overlap + 0.1 within threshold
    assert metrics.recall == pytest.approx(0.6, abs=0.01)
    assert metrics.accuracy_m == pytest.approx(0.5 * 0.25, abs=0.005)  # mean lateral gap of the far half


def test_empty_inputs_are_clear_errors() -> None:
    with pytest.raises(InputError, match="reconstruction has no points"):
        compare_point_sets(np.zeros((0, 3)), np.zeros((5, 3)), 0.1)
    with pytest.raises(InputError, match="ground truth has no points"):
        compare_point_sets(np.zeros((5, 3)), np.zeros((0, 3)), 0.1)


def test_frustum_culling_keeps_what_a_camera_sees() -> None:
    camera = CameraModel("pinhole", 100, 100, [[50, 0, 49.5], [0, 50, 49.5], [0, 0, 1]], [])
    # Camera at the origin looking along +x (camera z = world x); a 90° field of view.
    R_world_cam = np.array([[0, 0, 1], [-1, 0, 0], [0, -1, 0]], dtype=float)
    pose = make_transform(R_world_cam, np.zeros(3))[None]
    rng = np.random.default_rng(0)
    points = rng.uniform(-1, 1, (10_000, 3)) * [5, 5, 0.1]  # a slab around the camera
    mask = frustum_mask(points, pose, camera, near=0.05, far=10)
    x, y = points[:, 0], points[:, 1]
    expected = (x > 0.05) & (np.abs(y) < x * 50 / 50)  # half-width 50 px / focal 50 px
    assert mask.sum() > 1000
    assert (mask == expected).mean() > 0.995  # disagreements only at the frustum's edge pixels
    assert not mask[x < 0].any()  # nothing behind the camera


def test_lts_eval_mesh_json(tmp_path: Path) -> None:
    plane(0, 1).export(tmp_path / "rec.ply")
    plane(0, 1, z=0.05).export(tmp_path / "gt.ply")
    lts = Path(sys.executable).parent / "lts"
    result = subprocess.run(
        [
            lts,
            "eval",
            "--mesh",
            tmp_path / "rec.ply",
            "--gt",
            tmp_path / "gt.ply",
            "--threshold",
            "0.1",
            "--json",
        ],
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert result.returncode == 0, result.stderr
    metrics = json.loads(result.stdout)
    assert {"chamfer_m", "fscore", "precision", "recall", "threshold_m"} <= set(metrics)
    assert metrics["fscore"] == 1.0 and metrics["threshold_m"] == 0.1


def test_named_metrics_put_the_variant_before_the_unit():
    from eval.geometry import GeometricMetrics

    metrics = GeometricMetrics(0.01, 0.02, 0.015, 0.9, 0.8, 0.85, 0.1)
    assert metrics.named() == {"accuracy_m": 0.01, "completeness_m": 0.02, "chamfer_m": 0.015,
                               "precision": 0.9, "recall": 0.8, "fscore": 0.85}  # fmt: skip
    visible = {"accuracy_visible_m", "completeness_visible_m", "chamfer_visible_m"}
    visible |= {"precision_visible", "recall_visible", "fscore_visible"}
    assert set(metrics.named("visible")) == visible


def test_distances_to_the_surface_do_not_depend_on_the_scene_size() -> None:
    """A 2 x 2 m patch of a 200 x 200 m ground: 200 000 samples of the ground lie ~0.45 m apart,
    so sample to sample the patch, exactly on the ground, looks mostly farther than 10 cm; sample
    to surface it is all within."""
    ground = trimesh.creation.box([200, 200, 0.01])
    patch = trimesh.creation.box([2, 2, 0.01])
    rec, gt = sample_surface(patch, 20_000, seed=0), sample_surface(ground, 200_000, seed=1)
    assert compare_point_sets(rec, gt, 0.1).precision < 0.3
    to_gt = surface_distances(rec, ground)
    assert to_gt.max() < 0.006  # (the patch's sides lie inside the 1 cm thick ground)
    metrics = metrics_from_distances(to_gt, surface_distances(gt, patch), 0.1)
    assert metrics.precision == 1.0 and metrics.recall < 0.01
    with pytest.raises(InputError):
        metrics_from_distances(np.zeros(0), np.zeros(3), 0.1)
