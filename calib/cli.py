"""``lts calibrate``: intrinsics, LiDAR–camera extrinsic, time offset, or all a session supports.

``lts calibrate SESSION --out calib.yaml`` is routed to the ``session`` subcommand, so the
contract's short form and the named subcommands live side by side.
"""

from __future__ import annotations

import difflib
from pathlib import Path
from typing import Any

import click
import typer
from typer.core import TyperGroup

from rig.cli_support import HELP_MARKUP, console, emit_json, output_file_option
from rig.recording_options import (
    CAMERA_OPTION,
    DURATION_OPTION,
    RECORDING_ARGUMENT,
    START_OPTION,
    TOPICS_OPTION,
    open_from_options,
)


class _SessionDefaultGroup(TyperGroup):
    """Treat ``lts calibrate PATH ...`` as ``lts calibrate session PATH ...``, and options
    without a subcommand (``lts calibrate --out calib.yaml``: the recording forgotten) as the
    session's, whose error names the missing recording. A first word that names no file, has
    no dot or slash and is close to a subcommand's name (``lts calibrate tme``) is taken for a
    mistyped subcommand."""

    def parse_args(self, ctx: click.Context, args: list[str]) -> list[str]:
        if args and args[0] not in self.commands and args[0] not in ctx.help_option_names:
            word = args[0]
            typo = not Path(word).exists() and not any(c in word for c in "./\\")
            if typo and (close := difflib.get_close_matches(word, self.commands, 1)):
                raise click.UsageError(f"No such command {word!r}. Did you mean {close[0]!r}?", ctx)
            args = ["session", *args]
        return super().parse_args(ctx, args)


app = typer.Typer(
    rich_markup_mode=HELP_MARKUP,
    cls=_SessionDefaultGroup,
    help="Calibrate: camera intrinsics, LiDAR-camera extrinsic, time offset (or SESSION: all it supports).",
    no_args_is_help=True,
)


def _merge_into(base_path: Path | None, camera: Any = None, **updates: Any) -> Any:
    """Load ``base_path`` if it exists (keeping what this step does not change), apply the updates."""
    from rig.calibration import Calibration, load_calibration

    base = load_calibration(base_path) if base_path is not None and base_path.exists() else None
    # Without a base the file holds what this step found: no extrinsic unless it found one.
    calibration = Calibration(camera if camera is not None else base.camera, has_extrinsic=False)
    if base is not None:
        calibration.T_cam_lidar, calibration.time_offset_s = base.T_cam_lidar, base.time_offset_s
        calibration.quality, calibration.has_extrinsic = dict(base.quality), base.has_extrinsic
    quality = updates.pop("quality", {})
    for name, value in updates.items():
        setattr(calibration, name, value)
    calibration.has_extrinsic |= "T_cam_lidar" in updates
    calibration.quality.update(quality)
    return calibration


@app.command("intrinsics")
def intrinsics(
    images: list[Path] = typer.Argument(..., help="Board photographs (PNG/JPEG)."),
    out: Path = output_file_option(..., "--out", help="calib.yaml to write (its other blocks are kept)."),
    board: str | None = typer.Option(
        None, "--board", help="Chessboard inner corners COLSxROWS (searched when omitted)."
    ),
    square: float = typer.Option(1.0, "--square", help="Square side (m); scales only the board poses."),
    charuco: str | None = typer.Option(
        None, "--charuco", help="ChArUco board SQUARES_XxSQUARES_Y instead of a chessboard."
    ),
    marker: float = typer.Option(0.0, "--marker", help="ChArUco marker side (m); default 0.7 x square."),
    dictionary: str = typer.Option("DICT_5X5_100", "--dictionary", help="ChArUco ArUco dictionary."),
    model: str = typer.Option("pinhole", "--model", help="Camera model: pinhole or fisheye."),
    json_out: bool = typer.Option(False, "--json", help="Print one JSON object on stdout."),
) -> None:
    """Camera intrinsics from chessboard or ChArUco photographs."""
    from calib.boards import CharucoTarget, ChessboardTarget, detect_views, parse_grid, read_gray
    from calib.intrinsics import calibrate_intrinsics
    from rig.calibration import save_calibration
    from rig.errors import InputError

    grays = [(str(p), read_gray(p)) for p in images]
    sizes = {g.shape for _, g in grays}
    if len(sizes) != 1:
        raise InputError(f"images differ in size: {sorted(sizes)}", field="images")
    target: ChessboardTarget | CharucoTarget | None = None
    if charuco is not None:
        sx, sy = parse_grid(charuco, "--charuco")
        target = CharucoTarget(sx, sy, square, marker or 0.7 * square, dictionary)
    elif board is not None:
        target = ChessboardTarget(*parse_grid(board, "--board"), square)
    views, target = detect_views(grays, target, square)
    height, width = grays[0][1].shape
    result = calibrate_intrinsics(views, width, height, model)  # type: ignore[arg-type]
    save_calibration(_merge_into(out, camera=result.camera, quality=result.quality()), out)
    summary = {**result.to_json(), "views_found": len(views), "images": len(images), "out": str(out)}
    if isinstance(target, ChessboardTarget):
        summary["board"] = f"{target.cols}x{target.rows}"
    if json_out:
        emit_json(summary)
        return
    console.print(
        f"{model}: RMS {result.rms_px:.3f} px over {len(result.views_used)} views "
        f"({len(result.views_rejected)} rejected, board found in {len(views)}/{len(images)}), "
        f"fx {result.camera.fx:.2f} fy {result.camera.fy:.2f}, coverage {result.coverage:.0%}: "
        f"{result.verdict}{'' if not result.reasons else ' (' + '; '.join(result.reasons) + ')'}"
    )
    console.print(f"wrote {out}")


@app.command("extrinsic")
def extrinsic(
    image: list[Path] = typer.Option(..., "--image", help="Camera image (repeat for several pairs)."),
    points: list[Path] = typer.Option(
        ..., "--points", help="LiDAR cloud .pcd or KITTI .bin, one per --image."
    ),
    init: Path = typer.Option(..., "--init", help="calib.yaml with the camera and an initial T_cam_lidar."),
    out: Path = output_file_option(..., "--out", help="calib.yaml to write."),
    overlay: Path | None = typer.Option(
        None, "--overlay", help="PNG: LiDAR points on the first image, initial guess beside the result."
    ),
    board: str | None = typer.Option(
        None, "--board", help="Target-based: chessboard COLSxROWS inner corners seen in every pair."
    ),
    square: float = typer.Option(0.1, "--square", help="Target-based: square side (m)."),
    outline: str | None = typer.Option(
        None, "--outline", help="Target-based: board size WxH in mm (default: one square beyond the corners)."
    ),
    force: bool = typer.Option(
        False, "--force", help="Write the estimate into --out even when its verdict is not ok."
    ),
    json_out: bool = typer.Option(False, "--json", help="Print one JSON object on stdout."),
) -> None:
    """LiDAR-camera extrinsic from image + point-cloud pairs and a rough guess: targetless
    (edges + mutual information), or from a chessboard in several poses with --board.

    Only an estimate with verdict ok replaces the guess in --out (as `lts calibrate SESSION`
    does); otherwise --out keeps the --init extrinsic and its quality block says why, unless
    --force. The JSON's T_cam_lidar is always the estimate."""

    from calib.board_session import board_geometry
    from calib.overlay import write_comparison
    from calib.target_based import board_observations, calibrate_with_board
    from calib.targetless import read_pair, refine_extrinsic
    from rig.calibration import load_calibration, save_calibration
    from rig.errors import InputError

    if len(image) != len(points):
        raise InputError(
            f"{len(image)} --image but {len(points)} --points; give one cloud per image", field="--points"
        )
    start = load_calibration(init, needs_extrinsic=True)
    pairs = [read_pair(i, c) for i, c in zip(image, points, strict=True)]
    if board is None:
        result = refine_extrinsic(pairs, start.camera, start.T_cam_lidar)
    else:
        geometry = board_geometry(board, square, outline)
        observations = board_observations(pairs, start.camera, geometry.target)
        result = calibrate_with_board(observations, geometry.half_size, start.T_cam_lidar)
    applied = force or result.verdict == "ok"
    report = {**result.to_json(), "applied": applied}
    calibration = _merge_into(
        out if out.exists() else init,
        camera=start.camera,
        T_cam_lidar=result.T_cam_lidar if applied else start.T_cam_lidar,
        quality={"extrinsic": report},
    )
    save_calibration(calibration, out)
    if overlay is not None:
        write_comparison(
            overlay,
            pairs[0].image,
            start.camera,
            pairs[0].cloud.points,
            start.T_cam_lidar,
            result.T_cam_lidar,
        )
    if json_out:
        emit_json({**report, "out": str(out)})
        return
    rot, trans = result.change_from_init()
    console.print(
        f"moved {rot:.3f}° / {trans * 100:.1f} cm from the guess; "
        f"uncertainty ±{result.rotation_std_deg:.3f}° "
        f"±{result.translation_std_m * 100:.1f} cm: {result.verdict}"
        + ("" if not result.reasons else " (" + "; ".join(result.reasons) + ")")
    )
    if not applied:
        console.print("not applied: --out keeps the --init extrinsic (--force writes the estimate)")
    console.print(f"wrote {out}")


@app.command("time")
def time_offset(
    session: list[Path] = RECORDING_ARGUMENT,
    lidar_motion: str = typer.Option(
        "auto", "--lidar-motion", help="LiDAR-clock motion: imu (built-in gyro), odometry (KISS-ICP) or auto."
    ),
    init: Path | None = typer.Option(
        None, "--init", help="calib.yaml for the camera model if the session has none."
    ),
    out: Path | None = output_file_option(
        None, "--out", help="calib.yaml to update with the offset (when ok)."
    ),
    topics: str = TOPICS_OPTION,
    camera: int | None = CAMERA_OPTION,
    start: float = START_OPTION,
    duration: float | None = DURATION_OPTION,
    json_out: bool = typer.Option(False, "--json", help="Print one JSON object on stdout."),
) -> None:
    """Camera-LiDAR time offset from motion (angular speed of camera vs LiDAR clock): the
    recording needs camera frames and LiDAR scans or the LiDAR's IMU."""
    from calib.session_calib import calibrate_time
    from calib.session_data import load_session
    from rig.calibration import load_calibration, save_calibration
    from rig.errors import InputError

    data = load_session(open_from_options(session, topics, start, duration, camera))
    guess = load_calibration(init) if init is not None else None
    camera = data.camera or (guess.camera if guess else None)
    if camera is None:
        raise InputError("the session has no CameraInfo; give --init", path=data.path, field="camera_info")
    result, _ = calibrate_time(data, camera, lidar_motion)
    if out is not None:
        updates = {"time_offset_s": result.time_offset_s} if result.verdict == "ok" else {}
        base = out if out.exists() else init
        save_calibration(_merge_into(base, camera=camera, quality={"time": result.to_json()}, **updates), out)
    if json_out:
        emit_json(result.to_json())
        return
    console.print(
        f"time offset {result.time_offset_s * 1e3:+.2f} ms ± {result.std_s * 1e3:.2f} ms (1σ; 95 % within "
        f"± {result.interval_95 * result.std_s * 1e3:.2f} ms, correlation {result.correlation:.2f}, "
        f"{result.extra.get('lidar_motion')}): {result.verdict}"
        + ("" if not result.reasons else " (" + "; ".join(result.reasons) + ")")
    )


@app.command("session")
def session_command(
    session: list[Path] = RECORDING_ARGUMENT,
    out: Path = output_file_option(..., "--out", help="calib.yaml to write."),
    init: Path | None = typer.Option(
        None,
        "--init",
        help="calib.yaml with a rough T_cam_lidar for the targetless extrinsic to start from (or the "
        "camera alone, as lts calibrate intrinsics writes it); without one, a bag's /tf_static "
        "transform between the image's and the point cloud's frames, else the "
        "rotation that maps the LiDAR's angular velocity onto the camera's with a zero translation "
        "(needs a recording that turns; rough: 1.4-1.8 deg on the virtual room).",
    ),
    lidar_motion: str = typer.Option("auto", "--lidar-motion", help="imu, odometry or auto (see `time`)."),
    board: str | None = typer.Option(
        None,
        "--board",
        help="Target-based: chessboard COLSxROWS inner corners seen in the session (needs --init).",
    ),
    square: float = typer.Option(0.1, "--square", help="Target-based: square side (m)."),
    outline: str | None = typer.Option(
        None, "--outline", help="Target-based: board size WxH in mm (default: one square beyond the corners)."
    ),
    topics: str = TOPICS_OPTION,
    camera: int | None = CAMERA_OPTION,
    start: float = START_OPTION,
    duration: float | None = DURATION_OPTION,
    json_out: bool = typer.Option(False, "--json", help="Print one JSON object on stdout."),
) -> None:
    """Calibrate what a recording supports (also: lts calibrate RECORDING... --out ...): camera
    model, time offset, and the extrinsic (target-based with --board, else targetless: the LiDAR's
    map must look alike in 20 frames of the recording) from a rough one (--init, a bag's
    /tf_static, else found from the motion). Takes about a minute for the targetless extrinsic
    on 2 cores (a 10 s room: 25 s; a KITTI-size drive: 39-55 s)."""
    from calib.board_session import board_geometry
    from calib.session_calib import calibrate_session, report_lines
    from rig.calibration import load_calibration, save_calibration
    from rig.cpu_threads import cpu_threads

    guess = load_calibration(init) if init is not None else None
    geometry = board_geometry(board, square, outline) if board is not None else None
    recording = open_from_options(session, topics, start, duration, camera)
    with console.status("calibrating") as status:
        calibration, report = calibrate_session(
            recording,
            guess,
            lidar_motion,
            board=geometry,
            progress=lambda step: status.update(f"calibrating: {step}"),
            threads=cpu_threads(),
        )
    save_calibration(calibration, out)
    summary = {
        "T_cam_lidar": calibration.T_cam_lidar.tolist(),
        "time_offset_s": calibration.time_offset_s,
        "camera": calibration.camera.to_dict(),
        **report,
        "out": str(out),
    }
    if json_out:
        emit_json(summary)
        return
    for line in report_lines(report):
        console.print(line)
    console.print(f"wrote {out}")
