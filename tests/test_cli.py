"""The console scripts: help for every command, one-line errors, lazy imports."""

import os
import subprocess
import sys
from pathlib import Path

import pytest

BIN = Path(sys.executable).parent


@pytest.mark.parametrize("script", ["lts", "rig"])
def test_help_works(script: str) -> None:
    result = subprocess.run([BIN / script, "--help"], capture_output=True, text=True, timeout=60)
    assert result.returncode == 0, result.stderr
    assert "Usage" in result.stdout


def test_every_lts_command_has_help() -> None:
    import typer.main

    from lts.cli import app

    group = typer.main.get_command(app)

    def walk(command, path):
        yield path, command
        for name, sub in getattr(command, "commands", {}).items():
            yield from walk(sub, [*path, name])

    for path, command in walk(group, []):
        assert command.help or command.short_help, f"lts {' '.join(path)} has no help text"


def test_command_lists_and_usage_lines_read_as_the_help_texts_write_them() -> None:
    """A command is listed by one line of summary however its docstring is wrapped, an argument
    shows in capitals in the usage line (OUT_DIR), not as a Python name ({out_dir}), and a flag
    shows no type (not `--quick <bool>`, which reads as if it took a value)."""
    wide = {**os.environ, "COLUMNS": "400"}
    listing = subprocess.run(
        [BIN / "lts", "calibrate", "--help"], capture_output=True, text=True, timeout=60, env=wide
    ).stdout
    session = next(line for line in listing.splitlines() if line.startswith("│ session"))
    assert "camera model, time offset, and the extrinsic" in session
    usage = subprocess.run(
        [BIN / "lts", "sim", "--help"], capture_output=True, text=True, timeout=60, env=wide
    )
    assert "Usage: lts sim [OPTIONS] {OUT_DIR}" in usage.stdout
    flags = [line for line in usage.stdout.splitlines() if "--quick" in line or "--help" in line]
    assert len(flags) == 2 and not any("<bool>" in line for line in flags), flags
    assert "<int>" in usage.stdout  # options that take a value keep their type


def test_the_quick_demos_help_gives_the_iterations_it_trains() -> None:
    """The help is written out (the command line must not import the pipeline to print it): it
    must follow the constant the demo trains with."""
    from lts.demo import QUICK_ITERATIONS

    wide = {**os.environ, "COLUMNS": "400"}
    command = [BIN / "lts", "demo", "--help"]
    shown = subprocess.run(command, capture_output=True, text=True, timeout=60, env=wide)
    assert f"{QUICK_ITERATIONS} iterations" in shown.stdout, shown.stdout


def test_importing_packages_loads_no_hardware_or_heavy_library() -> None:
    """Nor the libraries that made every command line start 1 s slower (lts --help 2.5 -> 1.0 s)."""
    libraries = (
        "'depthai', 'open3d', 'usb', 'serial', 'ouster', 'torch', 'scipy.spatial', 'scipy.stats', 'trimesh'"
    )
    code = (
        "import sys, rig, calib, slam_bridge, splat, eval, lts, lts.cli, rig.cli;"
        f"heavy = [m for m in ({libraries}) if m in sys.modules];"
        "print(heavy); sys.exit(1 if heavy else 0)"
    )
    result = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert result.returncode == 0, result.stdout + result.stderr


def test_bad_trajectory_gives_one_line_error_and_exit_2(tmp_path: Path) -> None:
    bad = tmp_path / "bad.txt"
    bad.write_text("1.0 0 0 0 0 0 0 1\n2.0 0 0 x 0 0 0 1\n")
    result = subprocess.run(
        [BIN / "lts", "trajectory", "info", bad], capture_output=True, text=True, timeout=60
    )
    assert result.returncode == 2
    assert "Traceback" not in result.stderr
    assert f"{bad}:2" in result.stderr.replace("\n", "") and "tz" in result.stderr


def test_trajectory_convert_and_info_json(real_data: Path, tmp_path: Path) -> None:
    import json

    src = real_data / "trajectories_evo" / "fr2_desk_ORB.txt"
    out = tmp_path / "orb.csv"
    convert = subprocess.run(
        [BIN / "lts", "trajectory", "convert", src, out, "--to", "euroc"],
        capture_output=True,
        timeout=60,
    )
    assert convert.returncode == 0, convert.stderr
    info = subprocess.run(
        [BIN / "lts", "trajectory", "info", out, "--json"],
        capture_output=True,
        text=True,
        timeout=60,
    )
    summary = json.loads(info.stdout)
    assert summary["poses"] == sum(
        1 for line in src.read_text().splitlines() if line and not line.startswith("#")
    )
