"""``lts slam``: bring a mapper's mesh and trajectory into a SLAM folder."""

from __future__ import annotations

from dataclasses import asdict
from pathlib import Path

import typer

from rig.cli_support import HELP_MARKUP, console, emit_json, output_folder_option
from rig.recording_options import (
    DURATION_OPTION,
    POINTS_TOPIC_OPTION,
    RECORDING_ARGUMENT,
    START_OPTION,
    TOPICS_OPTION,
    open_from_options,
)

app = typer.Typer(
    rich_markup_mode=HELP_MARKUP,
    help="Import mesh-SLAM output (mesh + trajectory) into a SLAM folder.",
    no_args_is_help=True,
)


@app.command("import")
def import_command(
    source: Path = typer.Argument(
        ..., help="The mapper's output folder (or, for generic, a folder or mesh file)."
    ),
    out: Path = output_folder_option(..., "--out", help="SLAM folder to write: mesh.ply + trajectory.tum."),
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
    from slam_bridge.slam_import import import_slam_output, import_summary

    report = import_slam_output(
        source, out, fmt, mesh=mesh, trajectory=trajectory, bag=bag, odometry_topic=odometry_topic,
        cloud_topic=cloud_topic, times=times, rate=rate,
    )  # fmt: skip
    if json_out:
        emit_json({"out": str(out), **asdict(report)})
        return
    for line in import_summary(report, out):
        console.print(line)


@app.command("run")
def run_command(
    session: list[Path] = RECORDING_ARGUMENT,
    out: Path = output_folder_option(..., "--out", help="SLAM folder to write: mesh.ply + trajectory.tum."),
    calib: Path | None = typer.Option(
        None, "--calib", help="calib.yaml; only checked here (the mapper uses the LiDAR alone)."
    ),
    points_topic: str | None = POINTS_TOPIC_OPTION,
    topics: str = TOPICS_OPTION,
    start: float = START_OPTION,
    duration: float | None = DURATION_OPTION,
    voxel: float | None = typer.Option(
        None,
        "--voxel",
        min=0.001,
        help="Odometry voxel in m: each sweep is downsampled to it and the map's voxels are 3 times "
        "larger (default: 1/60 of the first sweep's 95th-percentile range, within 0.1-1 m).",
    ),
    tsdf_voxel: float | None = typer.Option(
        None,
        "--tsdf-voxel",
        min=0.001,
        help="TSDF voxel size in m (mesh resolution); default: 1/150 of the first sweep's 95th-percentile "
        "range, at least 0.04 m (about 0.04 m in rooms, 0.14 m on a street seen by a 64-beam LiDAR).",
    ),
    json_out: bool = typer.Option(False, "--json", help="Print one JSON object on stdout."),
) -> None:
    """Fallback mapper on a recording's LiDAR sweeps (per-point times): scan-to-map LiDAR odometry
    (VGICP), the moving points found and the static ones registered again, and a TSDF mesh of the
    de-skewed sweeps, written like an import, with a verdict on the trajectory."""
    from rich.progress import Progress

    from rig.calibration import load_calibration
    from slam_bridge.fallback_mapper import MapperConfig
    from slam_bridge.map_session import map_session

    if calib is not None:
        load_calibration(calib)
    recording = open_from_options(session, topics, start, duration)
    config = MapperConfig(voxel_size_m=voxel, tsdf_voxel_m=tsdf_voxel)
    with Progress(console=console, transient=True) as bar:
        task = bar.add_task("mapping (odometry + TSDF)", total=None)
        summary = map_session(
            recording, out, config, points_topic, progress=lambda i, n: bar.update(task, completed=i, total=n)
        )
    if json_out:
        emit_json(asdict(summary))
        return
    for line in summary.describe():
        console.print(line)
