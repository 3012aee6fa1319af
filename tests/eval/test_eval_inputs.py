"""``lts eval RUN``: RUN as an ``lts reconstruct`` folder, ``--gt`` as a mesh file in the scene's
frame, ``--lpips-weights``, and one-line errors for what is none of these."""

from __future__ import annotations

import json
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

sys.path.insert(0, str(Path(__file__).parent))
sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "splat"))
from lpips_weights_file import write_random_lpips_weights
from test_run_eval import make_tiny_run
from training_scene import corner_mesh

from eval.run_eval import CONTRACT_FIELDS
from eval.run_inputs import resolve_run_inputs

LTS = Path(sys.executable).parent / "lts"


@pytest.fixture(scope="module")
def inputs(tmp_path_factory) -> dict[str, Path]:
    """A tiny run, an ``lts reconstruct`` folder holding a copy of it in ``train/``, its
    virtual-rig ground truth, the same corner as an OBJ scan in the scene's frame, and a random
    LPIPS weights file."""
    root = tmp_path_factory.mktemp("eval_inputs")
    run_dir, gt_dir = make_tiny_run(root)
    shutil.copytree(run_dir, root / "reconstruct" / "train", ignore=shutil.ignore_patterns("checkpoints"))
    corner_mesh(24).export(root / "scan.obj")
    return {
        "run": run_dir,
        "gt": gt_dir,
        "reconstruct": root / "reconstruct",
        "scan": root / "scan.obj",
        "weights": write_random_lpips_weights(root / "lpips.pt"),
    }


def _lts_eval(*args) -> dict:
    result = subprocess.run(
        [LTS, "eval", *args, "--samples", "20000", "--no-report", "--json"],
        capture_output=True, text=True, timeout=300,
    )  # fmt: skip
    assert result.returncode == 0, result.stderr
    return json.loads(result.stdout)


def test_resolution_of_run_and_ground_truth(inputs) -> None:
    resolved = resolve_run_inputs(inputs["reconstruct"], inputs["gt"].parent)
    assert resolved.run_dir == inputs["reconstruct"] / "train" and resolved.gt == inputs["gt"]
    resolved = resolve_run_inputs(inputs["run"], inputs["scan"])
    assert resolved.run_dir == inputs["run"] and resolved.gt == inputs["scan"]
    assert resolve_run_inputs(inputs["run"]).gt is None


def test_a_reconstruct_folder_is_evaluated_through_its_training_run_with_lpips(inputs) -> None:
    metrics = _lts_eval(inputs["reconstruct"], "--lpips-weights", inputs["weights"])
    assert set(CONTRACT_FIELDS) <= set(metrics)
    assert metrics["run_dir"] == str(inputs["reconstruct"] / "train")
    assert isinstance(metrics["lpips"], float) and metrics["lpips"] >= 0 and "lpips" not in metrics["reasons"]
    assert metrics["psnr"] is not None
    assert json.loads((inputs["reconstruct"] / "train" / "eval.json").read_text()) == metrics


def test_a_mesh_file_is_ground_truth_in_the_scene_frame(inputs) -> None:
    metrics = _lts_eval(inputs["run"], "--gt", inputs["scan"])
    # the scan is the true corner in the scene's frame: as good as the aligned virtual-rig truth
    assert metrics["fscore"] > 0.9 and metrics["chamfer_m"] < 0.05
    assert metrics["gt_alignment_rmse_m"] is None and "mesh file" in metrics["reasons"]["gt_alignment_rmse_m"]
    assert metrics["hole_reference"] == "ground_truth" and metrics["hole_fraction_leaned"] is not None
    if metrics["physics_probes"] is None:
        assert "physics" in metrics["reasons"]
    else:
        assert metrics["physics_probes"] > 0 and metrics["fall_through_rate"] < 0.5


def test_without_lpips_weights_the_report_says_how_to_get_them(
    inputs, lts_cli, tmp_path, monkeypatch
) -> None:
    run_dir = tmp_path / "run"
    shutil.copytree(inputs["run"], run_dir, ignore=shutil.ignore_patterns("checkpoints"))
    # empty caches hide any weights of this machine; the rasteriser, built in $LTS_CACHE_DIR too,
    # is already loaded in this process by the fixture's training
    monkeypatch.setenv("LTS_CACHE_DIR", str(tmp_path / "empty-cache"))
    monkeypatch.setenv("TORCH_HOME", str(tmp_path / "empty-torch"))
    code, out, err = lts_cli("eval", run_dir, "--no-physics", "--samples", "20000", "--json")
    assert code == 0, err
    metrics = json.loads(out)
    assert metrics["lpips"] is None and "lts weights download" in metrics["reasons"]["lpips"]
    assert "lts weights download" in (run_dir / "report.html").read_text(encoding="utf-8")


@pytest.mark.parametrize(
    ("args", "expected"),
    [
        (["{empty}"], "not a training run folder: expected model.pt and run.json"),
        (["{run}", "--gt", "{notes}"], "notes.txt: --gt: expected a mesh file (PLY/OBJ/GLB)"),
        (["{run}", "--gt", "{missing}"], "missing.ply: --gt: no such ground-truth folder or mesh file"),
        (["{run}", "--gt", "{empty}"], "expected a ground-truth folder with mesh.ply and trajectory.tum"),
        (["{run}", "--lpips-weights", "{notes}"], "notes.txt: not a torch weights file"),
    ],
)
def test_bad_inputs_are_one_line_errors(inputs, lts_cli, tmp_path, args, expected) -> None:
    (tmp_path / "empty").mkdir()
    (tmp_path / "notes.txt").write_text("not a mesh\n")
    paths = {"run": inputs["run"], "empty": tmp_path / "empty", "notes": tmp_path / "notes.txt"}
    paths["missing"] = tmp_path / "missing.ply"
    code, out, err = lts_cli("eval", *(a.format(**paths) for a in args), "--no-physics", "--json")
    assert code == 2 and out == ""
    assert expected in err and len(err.strip().splitlines()) == 1, err
