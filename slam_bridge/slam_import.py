"""Bring any supported mapper's output into a SLAM folder: the format told from the files, one
entry point for ``lts slam import`` and ``lts reconstruct --slam``."""

from __future__ import annotations

from dataclasses import asdict
from pathlib import Path

from rig.errors import InputError
from slam_bridge.mesh_cleanup import CleanupReport

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
    if _holds_one_mesh_and_one_trajectory(source):
        return "generic"
    raise InputError(
        "cannot tell which mapper wrote this folder; name it with lts slam import --format "
        f"({', '.join(IMPORT_FORMATS)}), whose output lts reconstruct --slam takes",
        path=source,
    )


def _holds_one_mesh_and_one_trajectory(folder: Path) -> bool:
    """``folder`` (recursively) holds one mesh file and one trajectory file, as a generic import
    (or the SLAM folder ``lts slam run`` and ``lts slam import`` write) does."""
    from slam_bridge.generic import MESH_SUFFIXES, TRAJECTORY_SUFFIXES, files_with_suffix

    return all(len(files_with_suffix(folder, s)) == 1 for s in (MESH_SUFFIXES, TRAJECTORY_SUFFIXES))


def import_slam_output(
    source: Path,
    out: Path,
    fmt: str | None = None,
    *,
    mesh: Path | None = None,
    trajectory: Path | None = None,
    bag: Path | None = None,
    odometry_topic: str | None = None,
    cloud_topic: str = "/cloud_registered",
    times: Path | None = None,
    rate: float | None = None,
) -> CleanupReport:
    """Import ``source`` (a mapper's output folder, a bag, or a mesh file) into the SLAM folder
    ``out``; ``fmt`` (one of :data:`IMPORT_FORMATS`) is detected from the files when ``None``. The
    other arguments are the formats' options (see ``lts slam import --help``)."""
    fmt = fmt or detect_import_format(source, explicit_files=mesh is not None)
    if fmt == "immesh":
        from slam_bridge.immesh import ODOMETRY_TOPIC, import_immesh

        return import_immesh(
            source, out, bag=bag, odometry_topic=odometry_topic or ODOMETRY_TOPIC, cloud_topic=cloud_topic
        )
    if fmt == "pin-slam":
        from slam_bridge.pin_slam import import_pin_slam

        return import_pin_slam(source, out)
    if fmt == "fast-lio":
        from slam_bridge.fast_lio import ODOMETRY_TOPIC, import_fast_lio

        return import_fast_lio(source, out, trajectory, odometry_topic or ODOMETRY_TOPIC, bag)
    if fmt == "generic":
        from slam_bridge.generic import MESH_SUFFIXES, TRAJECTORY_SUFFIXES, find_single, import_generic

        mesh_path = mesh or (source if source.is_file() else find_single(source, MESH_SUFFIXES, "mesh"))
        traj_path = trajectory or find_single(source, TRAJECTORY_SUFFIXES, "trajectory")
        return import_generic(mesh_path, traj_path, out, times_path=times, rate_hz=rate)
    raise InputError(f"unknown format {fmt!r}; expected one of {', '.join(IMPORT_FORMATS)}", field="--format")


def import_summary(report: CleanupReport, out: Path) -> list[str]:
    """What an import wrote and cleaned, and where its mesh and trajectory came from, as lines of text."""
    lines = [
        f"wrote {out}/mesh.ply and trajectory.tum (removed {report.unused_vertices} unused vertices, "
        f"{report.degenerate_faces} degenerate and {report.duplicate_faces} duplicate faces; "
        f"re-oriented {report.flipped_faces} faces)"
    ]
    summary = asdict(report)
    if "trajectory_from" in summary:
        checked = summary.get("log_vs_bag_m")
        lines.append(
            f"mesh from {summary['mesh_from']}; trajectory from {summary['trajectory_from']}"
            + ("" if checked is None else f" (the log agrees to {checked * 1000:.2f} mm)")
        )
    return lines
