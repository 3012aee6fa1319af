"""``lts eval --mesh REC --gt GT``: geometric accuracy of one mesh against another."""

from __future__ import annotations

from pathlib import Path

import typer

from rig.cli_support import console, emit_json


def eval_command(
    mesh: Path = typer.Option(..., "--mesh", help="Reconstructed mesh (PLY/OBJ/GLB)."),
    gt: Path = typer.Option(..., "--gt", help="Ground-truth mesh."),
    threshold: float = typer.Option(0.1, "--threshold", help="F-score distance threshold in metres."),
    samples: int = typer.Option(200_000, "--samples", help="Points sampled by area on each mesh."),
    seed: int = typer.Option(0, "--seed", help="Seed of the surface sampling."),
    json_out: bool = typer.Option(False, "--json", help="Print one JSON object on stdout."),
) -> None:
    """Compare a mesh with ground truth: Chamfer-L1 and precision/recall/F-score (no culling)."""
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
