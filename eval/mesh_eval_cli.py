"""``lts eval``: a training run (``lts eval RUN``, see :mod:`eval.run_eval_cli`) or one mesh
against another (``lts eval --mesh REC --gt GT``)."""

from __future__ import annotations

from pathlib import Path

import typer

from eval.cli_options import GT_HELP, THRESHOLD_OPTION
from rig.cli_support import console, emit_json
from rig.errors import InputError


def eval_command(
    run_dir: Path | None = typer.Argument(
        None,
        metavar="RUN",
        help="Training run folder (lts train --out) or lts reconstruct --out folder (its train/); leave "
        "out to compare --mesh with --gt.",
    ),
    mesh: Path | None = typer.Option(
        None, "--mesh", help="Reconstructed mesh (PLY/OBJ/GLB), instead of RUN."
    ),
    gt: Path | None = typer.Option(
        None,
        "--gt",
        help=f"With --mesh: the ground-truth mesh. With RUN: {GT_HELP}.",
    ),
    threshold: float = THRESHOLD_OPTION,
    samples: int = typer.Option(200_000, "--samples", help="Points sampled by area on each mesh."),
    seed: int = typer.Option(0, "--seed", min=0, help="Seed of the surface sampling (--mesh form)."),
    report: bool = typer.Option(
        True, "--report/--no-report", help="RUN form: write report.html in the run folder."
    ),
    physics: bool = typer.Option(
        True, "--physics/--no-physics", help="RUN form: run the pybullet probe test (with --gt)."
    ),
    device: str = typer.Option("cpu", "--device", help="RUN form: cpu or cuda, where the model renders."),
    lpips_weights: Path | None = typer.Option(
        None,
        "--lpips-weights",
        help="RUN form: LPIPS weights file (lts weights download writes one to the cache, which is the "
        "default); without weights LPIPS is null.",
    ),
    seams: Path | None = typer.Option(
        None,
        "--seams",
        help="RUN form: check holes and fall-through at the seams of this block run's partition.json "
        "(default: the run's own, when it was trained with --blocks).",
    ),
    test_views: Path | None = typer.Option(
        None,
        "--test-views",
        metavar="SCENE",
        help="RUN form: score the test views on the held-out views of another scene of the same recording "
        "and map (a scene, training run or lts reconstruct folder) that RUN does not train on, so that runs "
        "with different keyframes compare on the same views. Prints the metrics; writes nothing in RUN.",
    ),
    json_out: bool = typer.Option(False, "--json", help="Print one JSON object on stdout."),
) -> None:
    """Evaluate a training run (photometry, geometry, leaned-view holes, physics, report), or compare
    a mesh with ground truth (--mesh REC --gt GT: Chamfer-L1 and precision/recall/F-score, no culling).

    RUN writes eval.json and report.html in the training run folder. Its test views are scored
    through the camera's blur the run fitted on its training views (camera_blur_px; psnr_sharp is
    the PSNR without it).
    """
    if run_dir is not None:
        if mesh is not None:
            raise InputError("give either RUN or --mesh, not both", field="--mesh")
        from eval.run_eval_cli import evaluate_run_command

        evaluate_run_command(
            run_dir, gt, threshold, samples, report, physics, device, lpips_weights, json_out, seams,
            test_views,
        )  # fmt: skip
        return
    if test_views is not None:
        raise InputError("scores the views of a run: give RUN", field="--test-views")
    if mesh is None:
        raise InputError("give a run folder (lts eval RUN_DIR) or a mesh (lts eval --mesh REC --gt GT)")
    if gt is None:
        raise InputError("--mesh needs --gt GT_MESH to compare with", field="--gt")
    from eval.geometry import compare_meshes
    from rig.mesh_io import load_mesh

    metrics = compare_meshes(load_mesh(mesh), load_mesh(gt), threshold, samples, seed)
    if json_out:
        emit_json(metrics.to_dict())
        return
    console.print(
        f"Chamfer-L1 {metrics.chamfer_m:.4f} m (accuracy {metrics.accuracy_m:.4f}, completeness "
        f"{metrics.completeness_m:.4f}); at {metrics.threshold_m:g} m: precision {metrics.precision:.3f}, "
        f"recall {metrics.recall:.3f}, F-score {metrics.fscore:.3f}"
    )
