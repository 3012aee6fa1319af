"""``lts trajectory``: inspect and convert trajectory files (TUM, KITTI, EuRoC, 4×4 lines)."""

from __future__ import annotations

from pathlib import Path

import typer

from rig.cli_support import HELP_MARKUP, console, emit_json, output_file_option
from rig.trajectory import Trajectory
from rig.trajectory_io import FORMATS, read_trajectory, write_trajectory

app = typer.Typer(
    rich_markup_mode=HELP_MARKUP, help="Inspect and convert trajectory files.", no_args_is_help=True
)

_FORMAT_HELP = f"File format: {', '.join(FORMATS)} (detected from the first line when omitted)."


def _read(path: Path, fmt: str | None, times: Path | None, rate: float | None) -> Trajectory:
    return read_trajectory(path, fmt, times_path=times, rate_hz=rate)


def trajectory_summary(trajectory: Trajectory) -> dict:
    """Counts, span, path length and end poses of a trajectory, as plain JSON-able values."""
    return {
        "poses": len(trajectory),
        "first_t_ns": trajectory.t_start_ns,
        "last_t_ns": trajectory.t_end_ns,
        "duration_s": trajectory.duration_s,
        "path_length_m": trajectory.path_length_m,
        "first_pose": trajectory.poses[0].tolist(),
        "last_pose": trajectory.poses[-1].tolist(),
    }


@app.command("info")
def info(
    path: Path = typer.Argument(..., help="Trajectory file."),
    fmt: str | None = typer.Option(None, "--format", help=_FORMAT_HELP),
    times: Path | None = typer.Option(None, "--times", help="KITTI/4x4: file with one time (s) per pose."),
    rate: float | None = typer.Option(None, "--rate", help="KITTI/4x4 without times: pose rate in Hz."),
    json_out: bool = typer.Option(False, "--json", help="Print one JSON object on stdout."),
) -> None:
    """Print the number of poses, time span and path length of a trajectory."""
    summary = trajectory_summary(_read(path, fmt, times, rate))
    if json_out:
        emit_json(summary)
        return
    console.print(
        f"{path}: {summary['poses']} poses over {summary['duration_s']:.3f} s, "
        f"path length {summary['path_length_m']:.3f} m"
    )


@app.command("convert")
def convert(
    src: Path = typer.Argument(..., help="Input trajectory file."),
    dst: Path = output_file_option(..., help="Output file (KITTI also writes STEM_times.txt beside it)."),
    to: str = typer.Option("tum", "--to", help=f"Output format: {', '.join(FORMATS)}."),
    fmt: str | None = typer.Option(None, "--format", help=_FORMAT_HELP),
    times: Path | None = typer.Option(
        None, "--times", help="KITTI/4x4 input: file with one time (s) per pose."
    ),
    rate: float | None = typer.Option(None, "--rate", help="KITTI/4x4 input without times: pose rate in Hz."),
) -> None:
    """Convert a trajectory between formats, keeping every number exactly."""
    trajectory = _read(src, fmt, times, rate)
    write_trajectory(trajectory, dst, to)
    console.print(f"wrote {len(trajectory)} poses to {dst} ({to})")
