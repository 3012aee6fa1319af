"""``lts trajectory compare``: ATE and RPE of an estimated trajectory against a reference, as evo's
``evo_ape`` / ``evo_rpe`` compute them (translation part; the rotation part of RPE too)."""

from __future__ import annotations

from dataclasses import asdict
from pathlib import Path

import typer

from rig.cli_support import console, emit_json
from rig.trajectory_io import read_trajectory


def compare_command(
    estimate: Path = typer.Argument(..., help="Estimated trajectory (TUM, KITTI, EuRoC or 4x4 lines)."),
    reference: Path = typer.Argument(
        ..., help="Reference trajectory (ground truth), any of the same formats."
    ),
    align: str = typer.Option(
        "poses",
        "--align",
        help="ATE alignment: poses (positions and orientations; stable for a robot driving straight) "
        "or positions (evo's default Umeyama fit, no scale).",
    ),
    delta: int = typer.Option(1, "--delta", help="RPE: pose pairs this many poses apart."),
    json_out: bool = typer.Option(False, "--json", help="Print one JSON object on stdout."),
) -> None:
    """ATE (after rigid alignment) and RPE of ESTIMATE against REFERENCE, compared at the
    estimate's stamps that the reference covers (interpolated there): both must share a clock."""
    from eval.trajectory_metrics import absolute_trajectory_error, relative_pose_error
    from rig.errors import InputError

    if align not in ("poses", "positions"):
        raise InputError(f"expected poses or positions, got {align!r}", field="--align")
    est, ref = read_trajectory(estimate), read_trajectory(reference)
    ate = absolute_trajectory_error(est, ref, use_orientation=align == "poses")
    rpe = relative_pose_error(est, ref, delta)
    report = {
        "ate_rmse_m": ate.rmse_m, "ate_mean_m": ate.mean_m, "ate_max_m": ate.max_m, "poses": ate.poses,
        **{f"rpe_{k}": v for k, v in asdict(rpe).items() if k not in ("pairs", "delta")},
        "rpe_pairs": rpe.pairs, "rpe_delta": rpe.delta, "align": align,
    }  # fmt: skip
    if json_out:
        emit_json(report)
        return
    console.print(
        f"ATE {100 * ate.rmse_m:.2f} cm rmse (mean {100 * ate.mean_m:.2f}, max {100 * ate.max_m:.2f}) over "
        f"{ate.poses} poses, aligned by {align}; RPE over {delta} pose(s): "
        f"{100 * rpe.translation_rmse_m:.2f} cm, {rpe.rotation_rmse_deg:.3f}° rmse"
    )
