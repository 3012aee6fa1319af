"""The layout of a training run folder (``RUN_DIR``), shared by ``lts train`` and ``lts eval``.

::

    config.yaml            the TrainConfig of the run (a resumed run must match it)
    run.json               {"scene": absolute SCENE_DIR, "config": "config.yaml"}
    metrics.jsonl          one JSON line per evaluation: iteration, elapsed_s, n_triangles, sigma,
                           opacity_floor, loss terms, test_psnr, test_ssim, test_depth_l1_m
    checkpoints/last.pt    the latest checkpoint (model, optimiser, statistics, RNG, counters)
    model.pt               the final model (splat.load_model)
    summary.json           TrainResult: time, triangles, test metrics, skips, densification log
    renders/NAME.png       test-view renders of the final model (through their colour maps)
    exposure.json          the colour map of every keyframe (splat.exposure): {"test_views": how the
                           held-out ones were chosen, "maps": {NAME: 3x3}}; absent when it learnt none
    keyframe_poses.tum     the training keyframes' camera poses as the run corrected them (learn_poses;
                           splat.pose_corrections), TUM at their stamps; absent when it learnt none
    mesh.ply|obj|glb       the exported triangles (opaque); collision.ply (+ .obj) for physics
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from rig.errors import InputError

CONFIG = "config.yaml"
RUN_INFO = "run.json"
METRICS = "metrics.jsonl"
CHECKPOINT = "checkpoints/last.pt"
MODEL = "model.pt"
SUMMARY = "summary.json"
RENDERS = "renders"
EXPOSURE = "exposure.json"
KEYFRAME_POSES = "keyframe_poses.tum"


def config_path(run_dir: Path) -> Path:
    return Path(run_dir) / CONFIG


def run_info_path(run_dir: Path) -> Path:
    return Path(run_dir) / RUN_INFO


def metrics_path(run_dir: Path) -> Path:
    return Path(run_dir) / METRICS


def checkpoint_path(run_dir: Path) -> Path:
    return Path(run_dir) / CHECKPOINT


def model_path(run_dir: Path) -> Path:
    return Path(run_dir) / MODEL


def summary_path(run_dir: Path) -> Path:
    return Path(run_dir) / SUMMARY


def exposure_path(run_dir: Path) -> Path:
    return run_dir / EXPOSURE


def renders_dir(run_dir: Path) -> Path:
    return Path(run_dir) / RENDERS


def scene_of(run_dir: str | Path) -> Path:
    """The scene folder a run was trained on (from ``run.json``)."""
    path = run_info_path(Path(run_dir))
    try:
        info = json.loads(path.read_text())
        return Path(info["scene"])
    except OSError:
        raise InputError(
            "not a training run folder (no run.json; make one with lts train)", path=run_dir
        ) from None
    except (json.JSONDecodeError, KeyError, TypeError) as exc:
        raise InputError(f"malformed run info ({exc})", path=path, field="scene") from None


def read_metrics(run_dir: str | Path) -> list[dict]:
    """The evaluation lines of ``metrics.jsonl`` (empty if the run has none yet)."""
    path = metrics_path(Path(run_dir))
    if not path.is_file():
        return []
    rows = []
    for number, line in enumerate(path.read_text().splitlines(), 1):
        try:
            rows.append(json.loads(line))
        except json.JSONDecodeError as exc:
            raise InputError(f"not a JSON line ({exc})", path=path, line=number) from None
    return rows


def read_color_maps(run_dir: Path) -> tuple[dict[str, np.ndarray], str | None]:
    """The colour matrices ``(3, 3)`` by keyframe name in ``RUN_DIR/exposure.json`` and how the
    held-out views' were chosen (empty and None when the run learnt none); an error naming the file
    when it is malformed."""
    path = exposure_path(run_dir)
    if not path.is_file():
        return {}, None
    try:
        data = json.loads(path.read_text())
        maps = {
            name: np.asarray(matrix, dtype=np.float64).reshape(3, 3) for name, matrix in data["maps"].items()
        }
        return maps, str(data["test_views"])
    except (ValueError, KeyError, TypeError, AttributeError) as exc:
        raise InputError(
            f"expected {{'test_views': ..., 'maps': {{NAME: 3x3}}}} ({exc})", path=path, field="maps"
        ) from None


def keyframe_poses_path(run_dir: Path) -> Path:
    return Path(run_dir) / KEYFRAME_POSES
