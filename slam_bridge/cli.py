"""``lts slam``: bring a mapper's mesh and trajectory into a SLAM folder."""

from __future__ import annotations

from dataclasses import asdict
from pathlib import Path

import numpy as np
import typer

from rig.cli_support import console, emit_json
from rig.errors import InputError

app = typer.Typer(
    help="Import mesh-SLAM output (mesh + trajectory) into a SLAM folder.", no_args_is_help=True
)

IMPORT_FORMATS = ("immesh", "pin-slam", "fast-lio", "generic")


def detect_import_format(source: Path, explicit_files: bool = False) -> str:
    """The import format of a mapper's output folder, when its files make it unambiguous (a bare
    bag is ImMesh's: no other format imports one alone)."""
    from slam_bridge.immesh import LOG_NAME, MESH_NAME
    from slam_bridge.mapper_bag import is_bag

    if not explicit_files and is_bag(source):
        return "immesh"
    if explicit_files or source.is_file():
        return "generic"
    if not source.is_dir():
        raise InputError("no such folder or file", path=source)
    if (source / MESH_NAME).is_file() or (source / "Log" / LOG_NAME).is_file():
        return "immesh"
    if (source / "mesh").is_dir() and any(source.glob("*_poses_tum.txt")):
        return "pin-slam"
    if (source / "scans.pcd").is_file() or (source / "PCD" / "scans.pcd").is_file():
        return "fast-lio"
    raise InputError(
        f"cannot tell which mapper wrote this folder; give --format ({', '.join(IMPORT_FORMATS)})",
        path=source,
    )


@app.command("import")
def import_command(
    source: Path = typer.Argument(
        ..., help="The mapper's output folder (or, for generic, a folder or mesh file)."
    ),
    out: Path = typer.Option(..., "--out", help="SLAM folder to write: mesh.ply + trajectory.tum."),
    fmt: str | None = typer.Option(
        None,
        "--format",
        help="immesh: SOURCE holds rec_mesh.ply and Log/kitti_log_voxelmap.txt (or the log at its root), "
        "and/or a bag recorded with ImMesh (odometry /aft_mapped_to_init, registered clouds "
        "/cloud_registered); SOURCE may also be the bag itself. The bag's odometry wins over the log; "
        "without rec_mesh.ply the mesh is made from the registered clouds. "
        "pin-slam: SOURCE holds mesh/*.ply and *_poses_tum.txt. "
        "fast-lio: SOURCE holds scans.pcd (or PCD/scans.pcd) and one bag with the odometry topic, or give "
        "--bag or --trajectory; the mesh is made from the map by Poisson reconstruction. "
        "generic: one mesh and one trajectory file (TUM/KITTI/EuRoC/4x4) in SOURCE, or --mesh/--trajectory "
        "(e.g. SLAMesh's PLY + KITTI poses with --rate). Detected from SOURCE's files when omitted.",
    ),
    mesh: Path | None = typer.Option(None, "--mesh", help="generic: the mesh file."),
    trajectory: Path | None = typer.Option(
        None, "--trajectory", help="generic / fast-lio: the trajectory file (TUM/KITTI/EuRoC/4x4)."
    ),
    bag: Path | None = typer.Option(
        None,
        "--bag",
        help="immesh / fast-lio: the bag (ROS 1 .bag, rosbag2 folder or .mcap) to read; default: the one "
        "bag at SOURCE's root.",
    ),
    odometry_topic: str | None = typer.Option(
        None,
        "--odometry-topic",
        help="immesh / fast-lio: odometry topic in the bag (default /aft_mapped_to_init for immesh, "
        "/Odometry for fast-lio).",
    ),
    cloud_topic: str = typer.Option(
        "/cloud_registered",
        "--cloud-topic",
        help="immesh: registered point clouds in the bag, meshed when there is no rec_mesh.ply.",
    ),
    times: Path | None = typer.Option(None, "--times", help="generic KITTI/4x4 trajectory: times file."),
    rate: float | None = typer.Option(None, "--rate", help="generic KITTI/4x4 trajectory without times: Hz."),
    json_out: bool = typer.Option(False, "--json", help="Print one JSON object on stdout."),
) -> None:
    """Import a mapper's mesh and trajectory: clean the mesh and write the SLAM folder."""
    fmt = fmt or detect_import_format(source, explicit_files=mesh is not None)
    if fmt == "immesh":
        from slam_bridge.immesh import ODOMETRY_TOPIC, import_immesh

        report = import_immesh(
            source, out, bag=bag, odometry_topic=odometry_topic or ODOMETRY_TOPIC, cloud_topic=cloud_topic
        )
    elif fmt == "pin-slam":
        from slam_bridge.pin_slam import import_pin_slam

        report = import_pin_slam(source, out)
    elif fmt == "fast-lio":
        from slam_bridge.fast_lio import ODOMETRY_TOPIC, import_fast_lio

        report = import_fast_lio(source, out, trajectory, odometry_topic or ODOMETRY_TOPIC, bag)
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
    if "trajectory_from" in summary:
        checked = summary.get("log_vs_bag_m")
        console.print(
            f"mesh from {summary['mesh_from']}; trajectory from {summary['trajectory_from']}"
            + ("" if checked is None else f" (the log agrees to {checked * 1000:.2f} mm)")
        )


@app.command("run")
def run_command(
    session: Path = typer.Argument(
        ..., help="Session .mcap with a LiDAR point-cloud topic (per-point times)."
    ),
    out: Path = typer.Option(..., "--out", help="SLAM folder to write: mesh.ply + trajectory.tum."),
    calib: Path | None = typer.Option(
        None, "--calib", help="calib.yaml; only checked here (the mapper uses the LiDAR alone)."
    ),
    points_topic: str | None = typer.Option(None, "--points-topic", help="Point-cloud topic, if several."),
    voxel: float | None = typer.Option(
        None, "--voxel", help="KISS-ICP voxel size in m (default: from the data)."
    ),
    tsdf_voxel: float = typer.Option(0.04, "--tsdf-voxel", help="TSDF voxel size in m (mesh resolution)."),
    json_out: bool = typer.Option(False, "--json", help="Print one JSON object on stdout."),
) -> None:
    """Fallback mapper: KISS-ICP LiDAR odometry (deskewed scans) and a TSDF mesh, written like an import."""
    from rich.progress import Progress

    from rig.calibration import load_calibration
    from rig.session import SessionReader
    from slam_bridge.fallback_mapper import MapperConfig, run_mapper
    from slam_bridge.mesh_cleanup import clean_mesh
    from slam_bridge.session_streams import find_topics
    from slam_bridge.slam_dir import write_slam_dir

    if calib is not None:
        load_calibration(calib)
    reader = SessionReader(session)
    topic = find_topics(reader, points=points_topic).points
    count = reader.topics()[topic].count
    config = MapperConfig(voxel_size_m=voxel, tsdf_voxel_m=tsdf_voxel)
    with Progress(console=console, transient=True) as bar:
        task = bar.add_task("mapping (KISS-ICP + TSDF)", total=count)
        result = run_mapper(reader.scans(topic), config, progress=lambda i: bar.update(task, completed=i + 1))
    mesh, _report = clean_mesh(
        result.mesh.vertices, result.mesh.faces, viewpoints=result.trajectory.translations
    )
    write_slam_dir(out, mesh, result.trajectory)
    summary = {
        "out": str(out),
        "scans_used": result.scans_used,
        "poses": len(result.trajectory),
        "faces": len(mesh.faces),
        "path_length_m": float(np.linalg.norm(np.diff(result.trajectory.translations, axis=0), axis=1).sum()),
    }
    if json_out:
        emit_json(summary)
        return
    console.print(
        f"wrote {out}/mesh.ply ({summary['faces']} faces) and trajectory.tum ({summary['poses']} poses, "
        f"{summary['path_length_m']:.2f} m)"
    )
