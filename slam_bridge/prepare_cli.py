"""``lts prepare``: build the keyframe scene folder that training reads."""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING

import typer

from rig.cli_support import console, emit_json, output_folder_option
from rig.recording_options import (
    CALIB_TF_HELP,
    CAMERA_OPTION,
    DURATION_OPTION,
    IMAGE_TOPIC_OPTION,
    POINTS_TOPIC_OPTION,
    RECORDING_ARGUMENT,
    START_OPTION,
    TOPICS_OPTION,
    calibration_option,
    open_from_options,
)
from slam_bridge.prepare_config import DEFAULT_MAX_SIZE, DEFAULT_MAX_TRAVEL_M

if TYPE_CHECKING:
    from slam_bridge.pose_refinement import RefinementReport

#: The progress bar's text for each step of building a scene.
STEP_NAMES = {
    "keyframes": "building keyframes",
    "features": "SIFT features",
    "matching": "matching keyframe pairs",
}

#: ``--max-size`` and ``--downscale``, shared with ``lts reconstruct``.
MAX_SIZE_OPTION = typer.Option(
    DEFAULT_MAX_SIZE,
    "--max-size",
    min=0,
    metavar="PX",
    help="Longest image side of the scene: larger recordings are scaled down to it (images area-averaged, "
    "intrinsics and normal priors with them; LiDAR depth is made at the final size). The default keeps a "
    "1920x1080 recording's CPU training within a few times the 320x240 demo's; smaller recordings are "
    "untouched. On a GPU pass more, or 0 for full size.",
)
DOWNSCALE_OPTION = typer.Option(
    1,
    "--downscale",
    min=1,
    metavar="N",
    help="Divide the recording's image size by N (then --max-size applies).",
)
#: ``--keyframe-distance``, shared with ``lts reconstruct``.
KEYFRAME_DISTANCE_OPTION = typer.Option(
    DEFAULT_MAX_TRAVEL_M,
    "--keyframe-distance",
    min=0.0,
    metavar="M",
    help="Also take a keyframe wherever the camera has moved M metres since the last one, before the "
    "interval is up (a car at 10 m/s would leave 5 m between keyframes 0.5 s apart; a walking robot never "
    "reaches it). 0: by time alone.",
)


def prepare_command(
    session: list[Path] = RECORDING_ARGUMENT,
    calib: Path = typer.Option(
        ..., "--calib", help=f"calib.yaml: camera, T_cam_lidar, time_offset_s; {CALIB_TF_HELP}."
    ),
    slam: Path = typer.Option(..., "--slam", help="SLAM folder (mesh.ply + trajectory.tum), from lts slam."),
    out: Path = output_folder_option(..., "--out", help="Scene folder to write."),
    interval: float | None = typer.Option(
        None,
        "--keyframe-interval",
        min=0.0,
        help="Seconds between keyframes; by default 0.5, or down to 0.2 so that a recording shorter than "
        "20 s still gives 40 keyframes.",
    ),
    keyframe_motion: tuple[float, float] | None = typer.Option(
        None,
        "--keyframe-motion",
        metavar="M DEG",
        help="Choose keyframes by motion instead of time: a new one after M metres or DEG degrees.",
    ),
    max_travel: float = KEYFRAME_DISTANCE_OPTION,
    test_every: int = typer.Option(
        8, "--test-every", min=0, help="Hold out every n-th keyframe for testing (0: none)."
    ),
    image_topic: str | None = IMAGE_TOPIC_OPTION,
    points_topic: str | None = POINTS_TOPIC_OPTION,
    topics: str = TOPICS_OPTION,
    camera: int | None = CAMERA_OPTION,
    start: float = START_OPTION,
    duration: float | None = DURATION_OPTION,
    normals: Path | None = typer.Option(
        None,
        "--normals",
        help="Folder of precomputed normal maps (T_NS.npy/.png by the frame's stamp, or the frame "
        "index in six digits; camera frame) to use instead of the SLAM mesh's normals.",
    ),
    sparse_points: bool = typer.Option(
        False,
        "--sparse-points",
        help="Triangulate COLMAP sparse points (the TS+ baseline starts from them; ours seeds camera-only "
        "triangles at those the LiDAR never reached): SIFT matched between keyframes that see the same "
        "surface of the SLAM mesh, guided by the poses; the same matches on every run.",
    ),
    refine_poses: bool = typer.Option(
        False,
        "--refine-poses",
        help="Refine the keyframe poses against the SLAM mesh (LiDAR points fixed, camera poses only; "
        "slow errors stay the LiDAR trajectory's). Held-out matches judge the result: a keyframe keeps its "
        "LiDAR pose unless its held-out reprojection error drops, and the whole refinement is refused "
        "when the error over all keyframes does not.",
    ),
    max_size: int = MAX_SIZE_OPTION,
    downscale: int = DOWNSCALE_OPTION,
    json_out: bool = typer.Option(False, "--json", help="Print one JSON object on stdout."),
) -> None:
    """Keyframes with poses, undistorted images, LiDAR points and normal priors (see README)."""
    from dataclasses import asdict

    from rich.progress import Progress

    from slam_bridge.prepare_config import PrepareConfig
    from slam_bridge.scene_builder import build_scene

    recording = open_from_options(session, topics, start, duration, camera)
    calibration = calibration_option(calib, recording, image=image_topic, points=points_topic)
    config = PrepareConfig(
        keyframe_interval_s=interval,
        keyframe_min_motion=keyframe_motion,
        keyframe_max_travel_m=max_travel,
        test_every=test_every,
        image_topic=image_topic,
        points_topic=points_topic,
        normals_dir=normals,
        sparse_points=sparse_points,
        refine_poses=refine_poses,
        max_size=max_size,
        downscale=downscale,
    )
    with Progress(console=console, transient=True) as bar:
        task = bar.add_task(STEP_NAMES["keyframes"], total=None)
        built = build_scene(
            recording,
            calibration,
            slam,
            out,
            config,
            progress=lambda step, i, n: bar.update(task, description=STEP_NAMES[step], completed=i, total=n),
        )
    keyframes, refinement = built.keyframes, built.refinement
    summary = {
        "out": str(out),
        "keyframes": len(keyframes),
        "keyframe_interval_s": round(built.interval_s, 4),
        "train": sum(k.split == "train" for k in keyframes),
        "test": sum(k.split == "test" for k in keyframes),
        "pose_refinement": None if refinement is None else asdict(refinement),
        "matching": None if built.matching is None else asdict(built.matching),
        "triangulation_s": built.triangulation_s,
    }
    if built.matching_summary() is not None:
        console.print(built.matching_summary())
    if refinement is not None:
        console.print(refinement_summary(refinement))
    if json_out:
        emit_json(summary)
        return
    console.print(
        f"wrote {out}: {summary['keyframes']} keyframes ({summary['train']} train, {summary['test']} test), "
        f"{built.spacing}"
    )


def refinement_summary(report: RefinementReport) -> str:
    """One line on what ``--refine-poses`` did (for stderr)."""
    if report.refused:
        return f"pose refinement refused, LiDAR poses kept: {report.refused}"
    return (
        f"pose refinement: {report.refined} keyframes refined, {len(report.kept)} kept their LiDAR pose; "
        f"held-out reprojection error {report.heldout_px_before:.2f} -> {report.heldout_px_after:.2f} px; "
        f"poses moved up to {report.max_move_m * 100:.1f} cm / {report.max_turn_deg:.2f} deg "
        f"(median {report.median_move_m * 100:.1f} cm / {report.median_turn_deg:.2f} deg)"
    )
