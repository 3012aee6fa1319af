"""``lts prepare``: build the keyframe scene folder that training reads."""

from __future__ import annotations

from pathlib import Path

import typer

from rig.cli_support import console, emit_json


def prepare_command(
    session: Path = typer.Argument(..., help="Session .mcap (camera images + LiDAR point clouds)."),
    calib: Path = typer.Option(..., "--calib", help="calib.yaml: camera, T_cam_lidar, time_offset_s."),
    slam: Path = typer.Option(..., "--slam", help="SLAM folder (mesh.ply + trajectory.tum), from lts slam."),
    out: Path = typer.Option(..., "--out", help="Scene folder to write."),
    interval: float = typer.Option(0.5, "--keyframe-interval", help="Seconds between keyframes."),
    keyframe_motion: tuple[float, float] | None = typer.Option(
        None,
        "--keyframe-motion",
        metavar="M DEG",
        help="Choose keyframes by motion instead of time: a new one after M metres or DEG degrees.",
    ),
    test_every: int = typer.Option(8, "--test-every", help="Hold out every n-th keyframe for testing."),
    image_topic: str | None = typer.Option(None, "--image-topic", help="Image topic, if several."),
    points_topic: str | None = typer.Option(None, "--points-topic", help="Point-cloud topic, if several."),
    normals: Path | None = typer.Option(
        None,
        "--normals",
        help="Folder of precomputed normal maps (<t_ns> or <frame index:06d> .npy/.png, camera frame) "
        "to use instead of the SLAM mesh's normals.",
    ),
    sparse_points: bool = typer.Option(
        False, "--sparse-points", help="Triangulate COLMAP sparse points (needed by the TS+ baseline)."
    ),
    refine_poses: bool = typer.Option(
        False,
        "--refine-poses",
        help="Bundle-adjust keyframe poses with COLMAP (intrinsics fixed). On the virtual rig's room it "
        "moved poses by up to 47 cm and made points worse: use only when the LiDAR trajectory is poor.",
    ),
    json_out: bool = typer.Option(False, "--json", help="Print one JSON object on stdout."),
) -> None:
    """Keyframes with poses, undistorted images, LiDAR depth images and normal priors (see README)."""
    from rich.progress import Progress

    from rig.calibration import load_calibration
    from slam_bridge.scene_builder import PrepareConfig, build_scene

    calibration = load_calibration(calib)
    config = PrepareConfig(
        interval,
        keyframe_motion,
        test_every,
        image_topic=image_topic,
        points_topic=points_topic,
        normals_dir=normals,
        sparse_points=sparse_points,
        refine_poses=refine_poses,
    )
    with Progress(console=console, transient=True) as bar:
        task = bar.add_task("building keyframes", total=None)
        keyframes = build_scene(
            session,
            calibration,
            slam,
            out,
            config,
            progress=lambda i, n: bar.update(task, completed=i, total=n),
        )
    summary = {
        "out": str(out),
        "keyframes": len(keyframes),
        "train": sum(k.split == "train" for k in keyframes),
        "test": sum(k.split == "test" for k in keyframes),
    }
    if json_out:
        emit_json(summary)
        return
    console.print(
        f"wrote {out}: {summary['keyframes']} keyframes ({summary['train']} train, {summary['test']} test)"
    )
