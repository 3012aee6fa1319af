"""``lts eval RUN_DIR``: a tiny training run evaluated against its own ground truth."""

from __future__ import annotations

import json
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "splat"))
from training_scene import corner_mesh, write_training_scene

from eval.run_eval import CONTRACT_FIELDS, GT_FIELDS, evaluate_run
from rig.errors import InputError
from rig.trajectory import Trajectory
from rig.trajectory_io import write_tum
from slam_bridge.scene import load_scene
from splat.model import TriangleModel, load_model, save_model

LTS = Path(sys.executable).parent / "lts"


def make_tiny_run(root: Path) -> tuple[Path, Path]:
    """A 40-iteration run on the six-view corner scene and a ground-truth folder (the corner mesh
    and the keyframe poses, so the alignment is the identity). Returns ``(run_dir, gt_dir)``."""
    from splat.config import make_config
    from splat.trainer import train

    scene_dir = write_training_scene(root / "scene")
    config = make_config(
        "ours", "default", iterations=40, densify_every=20, eval_every=20, checkpoint_every=20,
        init_max_triangles=500, ground_fill=False,
    )  # fmt: skip
    train(scene_dir, root / "run", config, progress=False, log=lambda *_: None)
    gt_dir = root / "truth" / "ground_truth"
    gt_dir.mkdir(parents=True)
    corner_mesh(24).export(gt_dir / "mesh.ply")
    scene = load_scene(scene_dir)
    stamps = np.array([k.t_ns for k in scene.keyframes])
    write_tum(
        Trajectory.from_poses(stamps, np.stack([k.T_world_cam for k in scene.keyframes])),
        gt_dir / "trajectory.tum",
    )
    return root / "run", gt_dir


@pytest.fixture(scope="module")
def tiny_run(tmp_path_factory) -> tuple[Path, Path]:
    return make_tiny_run(tmp_path_factory.mktemp("run_eval"))


@pytest.fixture(scope="module")
def with_gt(tiny_run):
    run_dir, gt_dir = tiny_run
    return evaluate_run(run_dir, gt_dir.parent, threshold_m=0.1, samples=50_000)


def test_every_contract_field_and_sensible_numbers_against_the_ground_truth(tiny_run, with_gt) -> None:
    metrics = with_gt.metrics
    assert set(CONTRACT_FIELDS) <= set(metrics)
    summary = json.loads((tiny_run[0] / "summary.json").read_text())
    assert metrics["n_triangles"] == summary["n_triangles"]
    assert metrics["train_seconds"] == summary["train_seconds"] > 0
    assert metrics["threshold_m"] == 0.1
    # the warm start is the true corner, so geometry is good even after 40 iterations
    assert metrics["fscore"] > 0.9 and metrics["precision"] > 0.9 and metrics["recall"] > 0.9
    assert metrics["chamfer_m"] < 0.05
    assert metrics["fscore_visible"] > 0.9 and 0 < metrics["gt_visible_fraction"] <= 1
    # A sample is never farther from a surface than from that surface's nearest sample.
    for name in ("precision", "recall", "fscore", "precision_visible", "recall_visible", "fscore_visible"):
        surface = name.replace("_visible", "_visible_surface") if "visible" in name else f"{name}_surface"
        assert metrics[surface] >= metrics[name] - 1e-6
    assert metrics["chamfer_surface_m"] <= metrics["chamfer_m"]
    assert metrics["gt_alignment_rmse_m"] < 1e-6
    assert 10 < metrics["psnr"] < 60 and 0 < metrics["ssim"] <= 1
    assert metrics["psnr_color_aligned"] >= metrics["psnr"] - 0.05  # a fitted colour map only helps
    assert 10 < metrics["psnr_hard_edges"] < 60 and metrics["psnr_hard_edges"] != metrics["psnr"]
    assert metrics["depth_error_median_m"] < 0.05 and metrics["depth_error_pixels"] > 100
    assert metrics["hole_reference"] == "ground_truth"
    assert 0 <= metrics["hole_fraction_leaned"] < 0.1
    assert (metrics["lpips"] is None) == ("lpips" in metrics["reasons"])
    assert (metrics["psnr_above_lidar"] is None) == ("psnr_above_lidar" in metrics["reasons"])
    for name in ("psnr_sky", "sky_covered_fraction"):
        assert (metrics[name] is None) == (name in metrics["reasons"])
    assert metrics["psnr_static"] is None and "movers/" in metrics["reasons"]["psnr_static"]
    assert len(with_gt.views) == 1 and len(with_gt.leaned) == 4
    if metrics["physics_probes"] is None:
        assert "physics" in metrics["reasons"]
    else:
        assert metrics["physics_probes"] > 0 and 0 <= metrics["fall_through_rate"] <= 1
    json.dumps(metrics)  # plain data


def test_without_ground_truth_the_geometric_metrics_are_null_with_a_reason(tiny_run) -> None:
    metrics = evaluate_run(tiny_run[0], None, physics=False).metrics
    assert set(CONTRACT_FIELDS) <= set(metrics)
    for name in (*GT_FIELDS, "psnr_sky", "sky_covered_fraction"):
        assert metrics[name] is None and "--gt" in metrics["reasons"][name]
    assert metrics["psnr"] is not None and metrics["n_triangles"] > 0
    assert metrics["hole_reference"] == "slam_mesh" and metrics["hole_fraction_leaned"] is not None


def test_triangles_where_the_ground_truth_has_no_surface_count_as_covering_the_sky(
    tiny_run, with_gt, tmp_path
) -> None:
    # The truth without its wall: the wall the run reconstructed now stands where the truth is empty.
    corner = corner_mesh(24)
    floor = corner.submesh([np.flatnonzero(corner.triangles_center[:, 2] < 1e-6)], append=True)
    floor.export(tmp_path / "floor.ply")
    metrics = evaluate_run(tiny_run[0], tmp_path / "floor.ply", physics=False, samples=5_000).metrics
    assert metrics["sky_covered_fraction"] > 0.5
    assert 0 < metrics["psnr_sky"] < 60
    # With the wall in the truth, only what the run grew past the wall's ends covers its sky.
    assert with_gt.metrics["sky_covered_fraction"] < metrics["sky_covered_fraction"] - 0.3


def test_a_model_without_its_wall_has_holes_in_the_leaned_views(tiny_run, tmp_path) -> None:
    run_dir = tmp_path / "run"
    shutil.copytree(tiny_run[0], run_dir, ignore=shutil.ignore_patterns("checkpoints"))
    model = load_model(run_dir / "model.pt")
    floor = model.params["vertices"].detach()[:, :, 2].max(dim=1).values < 0.5
    params = {name: p.detach()[floor] for name, p in model.params.items()}
    save_model(TriangleModel(params, model.sigma, model.opacity_floor), run_dir / "model.pt")
    metrics = evaluate_run(run_dir, tiny_run[1], physics=False, samples=20_000).metrics
    assert metrics["hole_fraction_leaned"] > 0.3  # the back wall fills much of each view
    assert metrics["hole_fraction_test"] > 0.3


def test_lts_eval_run_json_prints_the_contract_and_writes_eval_json(tiny_run) -> None:
    run_dir, gt_dir = tiny_run
    result = subprocess.run(
        [LTS, "eval", run_dir, "--gt", gt_dir, "--samples", "20000", "--no-report", "--json"],
        capture_output=True, text=True, timeout=300,
    )  # fmt: skip
    assert result.returncode == 0, result.stderr
    metrics = json.loads(result.stdout)  # exactly one JSON object: native banners went to stderr
    assert set(CONTRACT_FIELDS) <= set(metrics)
    assert metrics["fscore"] > 0.9
    assert json.loads((run_dir / "eval.json").read_text()) == metrics


def test_lts_eval_needs_a_run_or_a_mesh(tmp_path) -> None:
    result = subprocess.run([LTS, "eval"], capture_output=True, text=True, timeout=120)
    assert result.returncode == 2 and "lts eval RUN_DIR" in result.stderr
    result = subprocess.run([LTS, "eval", tmp_path], capture_output=True, text=True, timeout=120)
    assert result.returncode == 2 and "run.json" in result.stderr


def test_model_renders_are_what_the_trainer_reports(tiny_run, with_gt) -> None:
    """The evaluation's PSNR uses the trainer's convention (clamped render, black background)."""
    summary = json.loads((tiny_run[0] / "summary.json").read_text())
    assert with_gt.metrics["psnr"] == pytest.approx(summary["test"]["test_psnr"], abs=0.05)


def test_renders_are_scored_through_the_camera_blur_the_run_fitted(tiny_run, with_gt, tmp_path) -> None:
    summary = json.loads((tiny_run[0] / "summary.json").read_text())
    width = summary["camera_blur"]["width_px"]
    assert with_gt.metrics["camera_blur_px"] == width
    assert with_gt.metrics["psnr_sharp"] == pytest.approx(summary["camera_blur"]["test_psnr_sharp"], abs=0.05)
    run_dir = tmp_path / "run"
    shutil.copytree(tiny_run[0], run_dir, ignore=shutil.ignore_patterns("checkpoints"))
    summary["camera_blur"]["width_px"] = width + 1.0
    (run_dir / "summary.json").write_text(json.dumps(summary))
    metrics = evaluate_run(run_dir, physics=False).metrics
    assert metrics["camera_blur_px"] == width + 1.0 and metrics["psnr_sharp"] == with_gt.metrics["psnr_sharp"]
    assert metrics["psnr"] != with_gt.metrics["psnr"]
    summary["camera_blur"]["width_px"] = "wide"
    (run_dir / "summary.json").write_text(json.dumps(summary))
    with pytest.raises(InputError, match=r"camera_blur\.width_px.*expected a width in pixels"):
        evaluate_run(run_dir, physics=False)


def other_scene(tiny_run, root: Path, change) -> Path:
    """A copy of the tiny run's scene folder whose ``scene.json`` ``change(data)`` edited."""
    scene_dir = load_scene(run_dir_scene(tiny_run[0])).root
    copy = root / "other_scene"
    shutil.copytree(scene_dir, copy)
    data = json.loads((copy / "scene.json").read_text())
    change(data)
    (copy / "scene.json").write_text(json.dumps(data))
    return copy


def run_dir_scene(run_dir: Path) -> Path:
    from splat import run_dir as layout

    return layout.scene_of(run_dir)


def test_scored_on_a_copy_of_its_own_scene_a_run_scores_the_same(tiny_run, with_gt, tmp_path) -> None:
    from eval.shared_views import views_scene

    copy = views_scene(other_scene(tiny_run, tmp_path, lambda data: None))
    shared = evaluate_run(tiny_run[0], tiny_run[1].parent, samples=50_000, physics=False, test_views=copy)
    for name in ("psnr", "ssim", "psnr_color_aligned", "lidar_fscore", "hole_fraction_leaned"):
        assert shared.metrics[name] == pytest.approx(with_gt.metrics[name], abs=1e-6), name
    assert shared.metrics["test_views_dir"] == str(copy.root) != shared.metrics["scene_dir"]


def _swap_splits(data: dict) -> None:
    for keyframe in data["keyframes"]:
        keyframe["split"] = "train" if keyframe["split"] == "test" else "test"


def _move_poses(data: dict) -> None:
    for keyframe in data["keyframes"]:
        keyframe["T_world_cam"][0][3] += 0.05


def _scale_camera(data: dict) -> None:
    data["camera"]["K"][0][0] *= 1.1


@pytest.mark.parametrize(
    ("change", "message"),
    [
        (_swap_splits, "every one of its test views is a training view of the run"),
        (_move_poses, "lie up to 0.050 m from the run's: not the same map"),
        (_scale_camera, "is not the run's"),
    ],
)
def test_another_scenes_views_that_do_not_fit_the_run_are_refused(
    tiny_run, tmp_path, change, message
) -> None:
    from eval.shared_views import held_out_views, views_scene

    with pytest.raises(InputError, match=message) as refused:
        held_out_views(
            load_scene(run_dir_scene(tiny_run[0])), views_scene(other_scene(tiny_run, tmp_path, change))
        )
    assert "other_scene" in str(refused.value)


def test_lts_eval_test_views_prints_and_writes_nothing_in_the_run(tiny_run, tmp_path) -> None:
    run_dir = tiny_run[0]
    before = {p.name: p.stat().st_mtime_ns for p in run_dir.iterdir()}
    copy = other_scene(tiny_run, tmp_path, lambda data: None)
    result = subprocess.run(
        [LTS, "eval", run_dir, "--test-views", copy, "--no-physics", "--json"],
        capture_output=True, text=True, timeout=300,
    )  # fmt: skip
    assert result.returncode == 0, result.stderr
    assert json.loads(result.stdout)["test_views_dir"] == str(copy)
    assert {p.name: p.stat().st_mtime_ns for p in run_dir.iterdir()} == before
    for args, message in (
        (["--test-views", tmp_path / "nowhere"], "no such scene or run folder"),
        (["--test-views", tmp_path], "expected a scene folder"),
    ):
        refused = subprocess.run([LTS, "eval", run_dir, *args], capture_output=True, text=True, timeout=120)
        assert refused.returncode == 2 and message in refused.stderr, refused.stderr
        assert "Traceback" not in refused.stderr
