"""``lts sim``: simulate a camera + LiDAR + IMU recording with ground truth."""

from __future__ import annotations

from pathlib import Path

import typer

from rig.cli_support import console, emit_json, output_folder_option


def sim(
    out_dir: Path = output_folder_option(..., help="Output folder: session.mcap and ground_truth/."),
    preset: str = typer.Option(
        "room",
        "--preset",
        help="Scene preset: room, office (furnished: chairs, plants, lamps, bookcases, photographic "
        "textures; walked hand-held: for image fidelity), corridor, floor (a 170 m corridor through a "
        "building floor, 2 minutes: for block training), stairs, boards (four chessboards, for "
        "calibration) or street (a city street driven by a car: traffic, sky, a 64-beam LiDAR).",
    ),
    mesh: Path | None = typer.Option(
        None, "--mesh", help="User mesh (PLY/OBJ/GLB, vertex colours or texture)."
    ),
    trajectory: Path | None = typer.Option(
        None, "--trajectory", help="Camera-to-world poses for --mesh: TUM, KITTI or one 4x4 matrix per line."
    ),
    rate: float = typer.Option(30.0, "--rate", help="Pose rate (Hz) of a trajectory file without times."),
    seed: int = typer.Option(0, "--seed", min=0, help="Seed: the same seed gives a bit-identical run."),
    duration: float | None = typer.Option(
        None,
        "--duration",
        help="Seconds of motion (presets). \\[default: 20, floor: 120]",
        show_default=False,
    ),
    speed: float | None = typer.Option(
        None,
        "--speed",
        help="Cruising speed along the preset's path (m/s); on the street the cars in the robot's lane "
        "drive at it too. \\[default: 0.45, office: 0.5, street: 3]",
        show_default=False,
    ),
    quick: bool = typer.Option(
        False,
        "--quick",
        help="Small run for tests: 3 s, 160x120, 8000 LiDAR points, moving from the first frame "
        "(--duration, --width, --height or --lidar-points given keep their value).",
    ),
    carrier: str | None = typer.Option(
        None,
        "--carrier",
        help="wheeled (camera ~0.45 m high), handheld or car (~1.65 m). \\[default: the preset's; wheeled, "
        "office: handheld, street: car]",
        show_default=False,
    ),
    fps: float = typer.Option(30.0, "--fps", help="Camera frame rate (Hz)."),
    width: int | None = typer.Option(
        None, "--width", help="Image width (px). \\[default: 320, street: 640]", show_default=False
    ),
    height: int | None = typer.Option(
        None, "--height", help="Image height (px). \\[default: 240]", show_default=False
    ),
    camera: str = typer.Option("pinhole", "--camera", help="Camera model: pinhole or fisheye."),
    image_format: str = typer.Option(
        "png", "--image-format", help="Frames in the session: png, jpeg or raw."
    ),
    image_noise: float = typer.Option(0.0, "--image-noise", help="Pixel noise std (grey levels)."),
    exposure_jitter: float = typer.Option(0.0, "--exposure-jitter", help="Per-frame gain std (relative)."),
    lidar: str | None = typer.Option(
        None,
        "--lidar",
        help="LiDAR: mid360 (Livox Mid-360-like, 360° non-repetitive), rosette (Livox Avia-like, 70° field "
        "of view), spinning (Ouster-like, 32 beams ±22.5°), velodyne64 (64 beams -24.8°..+2°, as KITTI's) "
        "or velodyne32 (32 beams -30°..+10°). \\[default: mid360, street: velodyne64]",
        show_default=False,
    ),
    lidar_points: int | None = typer.Option(
        None,
        "--lidar-points",
        min=1,
        help="Points per sweep of the mid360/rosette patterns. \\[default: 20000]",
        show_default=False,
    ),
    range_noise: float = typer.Option(0.015, "--range-noise", help="LiDAR range noise std (m)."),
    dropout: float = typer.Option(0.02, "--dropout", help="Fraction of LiDAR returns lost."),
    max_range: float | None = typer.Option(
        None, "--max-range", help="LiDAR maximum range (m). \\[default: 40, street: 80]", show_default=False
    ),
    time_offset: float = typer.Option(
        0.015, "--time-offset", help="Camera-LiDAR time offset (s), see calib.yaml."
    ),
    traffic: bool = typer.Option(
        True, "--traffic/--no-traffic", help="The vehicles drive (street); --no-traffic: a static scene."
    ),
    config: Path | None = typer.Option(
        None, "--config", help="Regenerate a run from its ground_truth/scene.yaml (other options ignored)."
    ),
    preview: Path | None = typer.Option(
        None, "--preview", help="Also write a PNG: a frame with a sweep on it."
    ),
    preview_at: float | None = typer.Option(
        None, "--preview-at", min=0.0, help="Time (s) of the preview frame (default: mid-run)."
    ),
    json_out: bool = typer.Option(False, "--json", help="Print one JSON summary object on stdout."),
) -> None:
    """Simulate a robot run through a scene: OUT_DIR/session.mcap and OUT_DIR/ground_truth/."""
    import cv2
    from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeElapsedColumn

    from rig.sim.config import SimConfig
    from rig.sim.preview import preview_image
    from rig.sim.simulate import prepare, record

    sized = {"duration_s": duration, "width": width, "height": height, "lidar_points": lidar_points}
    sized = {name: value for name, value in sized.items() if value is not None}  # the ones given
    if config is not None:
        cfg = SimConfig.from_scene_yaml(config)
    else:
        cfg = SimConfig(
            preset=preset,
            mesh=None if mesh is None else str(mesh),
            trajectory=None if trajectory is None else str(trajectory),
            trajectory_rate_hz=rate,
            seed=seed,
            speed_mps=speed,
            carrier=carrier,
            fps=fps,
            camera_model=camera,
            image_format=image_format,
            image_noise=image_noise,
            exposure_jitter=exposure_jitter,
            lidar=lidar,
            range_noise_m=range_noise,
            dropout=dropout,
            max_range_m=max_range,
            time_offset_s=time_offset,
            traffic=traffic,
            **sized,
        )
        if quick:
            cfg = cfg.quick(**sized)
    run = prepare(cfg)  # bad input fails here, before the progress bar appears
    columns = (TextColumn("simulating"), BarColumn(), MofNCompleteColumn(), TimeElapsedColumn())
    with Progress(*columns, console=console, transient=json_out) as bar:
        task = bar.add_task("sim", total=None)
        summary = record(run, out_dir, lambda done, total: bar.update(task, completed=done, total=total))
    if preview is not None:
        cv2.imwrite(str(preview), preview_image(run, preview_at))
        summary["preview"] = str(preview)
    if json_out:
        emit_json(summary)
        return
    console.print(
        f"{summary['frames']} frames, {summary['scans']} scans "
        f"(~{summary['points_per_scan_mean']:.0f} points each), "
        f"{summary['imu_samples']} IMU samples over {summary['duration_s']:.1f} s → {summary['session']} "
        f"({summary['session_bytes'] / 1e6:.1f} MB), ground truth in {summary['ground_truth']}"
    )
