"""``lts slam``: bring a mapper's mesh and trajectory into a SLAM folder."""

from __future__ import annotations

from dataclasses import asdict
from pathlib import Path

import typer

from rig.cli_support import console, emit_json
from rig.errors import InputError

app = typer.Typer(
    help="Import mesh-SLAM output (mesh + trajectory) into a SLAM folder.", no_args_is_help=True
)

IMPORT_FORMATS = ("immesh", "generic")


@app.command("import")
def import_command(
    source: Path = typer.Argument(
        ..., help="The mapper's output folder (or, for generic, a folder or mesh file)."
    ),
    out: Path = typer.Option(..., "--out", help="SLAM folder to write: mesh.ply + trajectory.tum."),
    fmt: str = typer.Option(
        ...,
        "--format",
        help="immesh: SOURCE holds rec_mesh.ply and Log/kitti_log_voxelmap.txt (or the log at its root). "
        "generic: one mesh and one trajectory file (TUM/KITTI/EuRoC/4x4) in SOURCE, or --mesh/--trajectory.",
    ),
    mesh: Path | None = typer.Option(None, "--mesh", help="generic: the mesh file."),
    trajectory: Path | None = typer.Option(None, "--trajectory", help="generic: the trajectory file."),
    times: Path | None = typer.Option(None, "--times", help="generic KITTI/4x4 trajectory: times file."),
    rate: float | None = typer.Option(None, "--rate", help="generic KITTI/4x4 trajectory without times: Hz."),
    json_out: bool = typer.Option(False, "--json", help="Print one JSON object on stdout."),
) -> None:
    """Import a mapper's mesh and trajectory: clean the mesh and write the SLAM folder."""
    if fmt == "immesh":
        from slam_bridge.immesh import import_immesh

        report = import_immesh(source, out)
    elif fmt == "generic":
        from slam_bridge.generic import MESH_SUFFIXES, TRAJECTORY_SUFFIXES, find_single, import_generic

        mesh_path = mesh or (source if source.is_file() else find_single(source, MESH_SUFFIXES, "mesh"))
        traj_path = trajectory or find_single(source, TRAJECTORY_SUFFIXES, "trajectory")
        report = import_generic(mesh_path, traj_path, out, times_path=times, rate_hz=rate)
    else:
        raise InputError(
            f"unknown format {fmt!r}; expected one of {', '.join(IMPORT_FORMATS)}", field="--format"
        )
    summary = {"out": str(out), **asdict(report)}
    if json_out:
        emit_json(summary)
        return
    console.print(
        f"wrote {out}/mesh.ply and trajectory.tum (removed {report.unused_vertices} unused vertices, "
        f"{report.degenerate_faces} degenerate and {report.duplicate_faces} duplicate faces; "
        f"re-oriented {report.flipped_faces} faces)"
    )
