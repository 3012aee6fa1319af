"""``lts reconstruct`` and ``lts demo``: the pipeline's commands, with a table of stages and metrics."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING

import typer

from rig.cli_support import console, emit_json, output_folder_option
from rig.recording_options import (
    CALIB_TF_HELP,
    CAMERA_OPTION,
    DURATION_OPTION,
    RECORDING_ARGUMENT,
    START_OPTION,
    TOPICS_OPTION,
    time_span,
)
from slam_bridge.prepare_cli import DOWNSCALE_OPTION, KEYFRAME_DISTANCE_OPTION, MAX_SIZE_OPTION
from splat.config import PRESET_HELP

if TYPE_CHECKING:
    from lts.pipeline import ReconstructResult

SUMMARY_KEYS = ("psnr", "ssim", "lpips", "fscore", "precision", "recall", "chamfer_m", "lidar_fscore",
                "hole_fraction_leaned", "n_triangles", "train_seconds")  # fmt: skip


def _log(message: str) -> None:
    console.print(message, highlight=False, markup=False)


def _run_stages(job: Callable[[], tuple[ReconstructResult, list]]) -> tuple[ReconstructResult, list]:
    """Run ``job``; a training stopped by Ctrl-C (checkpoint saved) or diverged ends with its message."""
    from splat.trainer import TrainingDivergedError, TrainingInterruptedError

    try:
        return job()
    except TrainingInterruptedError as exc:
        console.print(f"{exc}; rerun the same command to continue", highlight=False)
        raise typer.Exit(130) from None
    except TrainingDivergedError as exc:
        console.print(f"error: training diverged: {exc}", highlight=False)
        raise typer.Exit(1) from None


def _summary(result: ReconstructResult, extra_stages=()) -> dict:
    stages = [*extra_stages, *result.stages]
    return {
        **result.metrics,
        "stages": {s.name: {"status": s.status, "seconds": s.seconds} for s in stages},
        "report": str(result.run_dir / "train" / "report.html"),
    }


def _print_table(summary: dict) -> None:
    from rich.table import Table

    stages = Table(title="stages")
    for column in ("stage", "status", "seconds"):
        stages.add_column(column)
    for name, s in summary["stages"].items():
        stages.add_row(name, s["status"], f"{s['seconds']:.1f}")
    console.print(stages)
    metrics = Table(title="metrics")
    metrics.add_column("metric")
    metrics.add_column("value", justify="right")
    for key in SUMMARY_KEYS:
        value = summary.get(key)
        metrics.add_row(
            key, "—" if value is None else f"{value:.4g}" if isinstance(value, float) else str(value)
        )
    console.print(metrics)
    console.print(f"report: {summary['report']}", highlight=False)


def reconstruct_command(
    session: list[Path] = RECORDING_ARGUMENT,
    out: Path = output_folder_option(
        ..., "--out", "-o", help="Run folder: calib.yaml, slam/, scene/, train/, report."
    ),
    calib: Path | None = typer.Option(
        None, "--calib", help=f"A finished calibration (skips lts calibrate): a calib.yaml, {CALIB_TF_HELP}."
    ),
    init: Path | None = typer.Option(
        None,
        "--init",
        help="A rough calibration (e.g. the rig's CAD values) for lts calibrate session to refine, or "
        "the camera alone (lts calibrate intrinsics); without an extrinsic from it, a bag's /tf_static "
        "one is refined, else one found from the motion.",
    ),
    slam: Path | None = typer.Option(
        None,
        "--slam",
        help="A mapper's output (ImMesh, PIN-SLAM, FAST-LIO or mesh + trajectory) to import "
        "instead of running the fallback mapper.",
    ),
    gt: Path | None = typer.Option(
        None, "--gt", help="Ground-truth folder (mesh.ply + trajectory.tum) to score against."
    ),
    method: str = typer.Option("ours", help="Training method (see lts train --help)."),
    preset: str = typer.Option("default", help=f"Training preset: {PRESET_HELP}."),
    iterations: int | None = typer.Option(None, min=1, help="Override the preset's iteration count."),
    device: str = typer.Option("cpu", help="cpu or cuda for training."),
    seed: int = typer.Option(0, min=0, help="Training seed."),
    exposure: str = typer.Option(
        "auto",
        "--exposure",
        help="auto, on or off: a colour matrix per training image (see lts train --help).",
    ),
    learn_poses: bool = typer.Option(
        False,
        "--learn-poses",
        help="Learn a correction of each training keyframe's pose with the triangles (see lts train --help).",
    ),
    blocks: str | None = typer.Option(
        None,
        "--blocks",
        metavar="auto|N",
        help="Train in spatial blocks on Ray and merge them (long trajectories): auto sizes them by "
        "budgets, N makes N (see lts train --help).",
    ),
    ray_address: str | None = typer.Option(
        None, "--ray-address", help="A Ray cluster for --blocks (default: a local Ray instance)."
    ),
    keyframe_interval: float | None = typer.Option(
        None,
        "--keyframe-interval",
        min=0.0,
        help="Seconds between keyframes (lts prepare's default: 0.5, or down to 0.2 so that a short "
        "recording gives 40; 0: every frame).",
    ),
    keyframe_distance: float = KEYFRAME_DISTANCE_OPTION,
    max_size: int = MAX_SIZE_OPTION,
    downscale: int = DOWNSCALE_OPTION,
    topics: str = TOPICS_OPTION,
    camera: int | None = CAMERA_OPTION,
    start: float = START_OPTION,
    duration: float | None = DURATION_OPTION,
    json_out: bool = typer.Option(
        False, "--json", help="Print the metrics and per-stage seconds as one JSON object."
    ),
) -> None:
    """Calibrate, map (or import), prepare, train and evaluate one recording (a session, or a bag
    read in place).

    Every stage writes into --out and is skipped on a rerun when its inputs and options are
    unchanged, so a crash or Ctrl-C resumes where it stopped (training from its last checkpoint)
    and changing a training option retrains without redoing calibration or mapping.
    """
    from lts.pipeline import ReconstructOptions, reconstruct

    options = ReconstructOptions(
        session, out, calib, init, slam, gt, method, preset, iterations, device, seed, keyframe_interval,
        keyframe_distance, max_size=max_size, downscale=downscale, topics=topics,
        span=time_span(start, duration), camera=camera, exposure=exposure, learn_poses=learn_poses,
        blocks=blocks, ray_address=ray_address,
    )  # fmt: skip
    result, _ = _run_stages(lambda: (reconstruct(options, _log), []))
    summary = _summary(result)
    _print_table(summary)
    if json_out:
        emit_json(summary)


def demo_command(
    out: Path = output_folder_option(
        Path("demo_out"), "--out", "-o", help="Where the scene, session and run go."
    ),
    quick: bool = typer.Option(
        False, "--quick", help="The simulator's 3 s, 160x120 room; the fast preset, 800 iterations (~1 min)."
    ),
    json_out: bool = typer.Option(
        False, "--json", help="Print the metrics and per-stage seconds as one JSON object."
    ),
) -> None:
    """Simulate a room, record it through the mock devices, reconstruct it and score it against the truth."""
    from lts.demo import run_demo

    result, demo_stages = _run_stages(lambda: run_demo(out, quick, _log))
    summary = _summary(result, demo_stages)
    _print_table(summary)
    if json_out:
        emit_json(summary)
