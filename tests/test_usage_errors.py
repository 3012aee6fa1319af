"""Every ``lts`` and ``rig`` command answers a usage mistake (an unknown option, a missing
argument) with Click's short usage and a one-line error, exit status 2, no traceback, and with
``--json`` nothing on stdout. The commands are found by walking the apps, so a new command is
covered without editing this test."""

from __future__ import annotations

import os
import subprocess
import sys
from concurrent.futures import ThreadPoolExecutor
from functools import partial
from pathlib import Path

import pytest
import typer.main

from lts.cli import app as lts_app
from rig.cli import app as rig_app

BIN = Path(sys.executable).parent


def _leaves() -> list[tuple[list[str], typer.main.click.Command]]:
    """``(command words, command)`` of every leaf command of both apps."""

    def walk(command, path):
        if getattr(command, "commands", None):
            for name, sub in command.commands.items():
                yield from walk(sub, [*path, name])
        else:
            yield path, command

    return [
        c
        for name, app in (("lts", lts_app), ("rig", rig_app))
        for c in walk(typer.main.get_command(app), [name])
    ]


def _commands() -> list[tuple[list[str], bool, bool]]:
    """``(command words, takes --json, has a required parameter)`` of every leaf command."""
    return [
        (
            words,
            any("--json" in getattr(p, "opts", []) for p in command.params),
            any(p.required for p in command.params),
        )
        for words, command in _leaves()
    ]


def _mistakes() -> list[tuple[list[str], str]]:
    """Each command line to try and the words its error must contain."""
    cases = []
    for words, json_option, required in _commands():
        cases.append(([*words, "--no-such-option"], "No such option"))
        if json_option:
            cases.append(([*words, "--json", "--no-such-option"], "No such option"))
        if required:
            cases.append((words, "Missing"))
            if json_option:
                cases.append(([*words, "--json"], "Missing"))
    return cases


def _run(args: list[str]) -> subprocess.CompletedProcess:
    # Niced: beside them another test file may be recording the virtual rig in real time, whose
    # mock devices fall behind when these dozens of interpreters take both cores.
    command = [BIN / args[0], *args[1:]]
    niced = partial(os.nice, 10)
    return subprocess.run(command, capture_output=True, text=True, timeout=120, preexec_fn=niced)


def test_every_command_has_a_one_line_summary_and_capital_argument_names() -> None:
    """Command lists show each command's one-line summary; usage lines name arguments in capitals,
    as the help texts write them (rig.cli_support.tidy_help)."""
    for words, command in _leaves():
        assert command.short_help and "\n" not in command.short_help, words
        for parameter in command.params:
            if parameter.param_type_name == "argument":
                assert parameter.metavar and parameter.metavar == parameter.metavar.upper(), words


def test_every_usage_mistake_is_short_usage_and_one_error_line() -> None:
    cases = _mistakes()
    assert len(cases) > 60  # every command of both apps
    with ThreadPoolExecutor(4) as pool:
        results = list(pool.map(_run, [args for args, _ in cases]))
    failures = []
    for (args, says), result in zip(cases, results, strict=True):
        lines = result.stderr.strip().splitlines()
        ok = (
            result.returncode == 2
            and result.stdout == ""
            and "Traceback" not in result.stderr
            and len(lines) == 3
            and lines[0].startswith(f"Usage: {args[0]} ")
            and lines[1].startswith("Try '")
            and lines[2].startswith("error: ")
            and says in lines[2]
        )
        if not ok:
            failures.append(f"{' '.join(args)} -> exit {result.returncode}: {result.stderr[-300:]!r}")
    assert not failures, "\n".join(failures)


@pytest.mark.parametrize("args", [["lts", "no-such-command"], ["rig", "no-such-command"]])
def test_an_unknown_command_is_a_usage_error(args: list[str]) -> None:
    result = _run(args)
    assert result.returncode == 2 and "No such command 'no-such-command'" in result.stderr
    assert "Traceback" not in result.stderr


#: The parameters that name what a command writes.
OUTPUT_PARAMETERS = ("out", "out_dir", "dst")


def test_every_output_path_is_checked_on_the_command_line() -> None:
    """A folder to write into refuses a file; a file to write refuses a folder and a folder that
    does not exist (rig.cli_support.output_folder_option / output_file_option)."""
    outputs = [
        (words, p) for words, command in _leaves() for p in command.params if p.name in OUTPUT_PARAMETERS
    ]
    assert len(outputs) > 15
    # Typer keeps the declared Path checks on the parameter's info.
    infos = [(words, p.type_descriptor.parameter_info) for words, p in outputs]
    unchecked = [
        " ".join(words)
        for words, info in infos
        if info.file_okay and (info.dir_okay or info.callback is None)
    ]
    assert not unchecked


def test_an_output_path_of_the_wrong_kind_stops_before_any_work(tmp_path: Path) -> None:
    a_file = tmp_path / "notes.txt"
    a_file.write_text("not a folder")
    missing = tmp_path / "missing" / "calib.yaml"
    under_a_file = a_file / "run"
    cases = [
        (["lts", "demo", "--quick", "--out", str(under_a_file)], f"{a_file} is a file, not a folder"),
        (["lts", "sim", str(under_a_file / "deeper"), "--quick"], f"{a_file} is a file, not a folder"),
        (
            ["rig", "record", "--sim", str(tmp_path), "--out", str(under_a_file / "s.mcap")],
            f"{a_file} is a file, not a folder",
        ),
        (["lts", "sim", str(a_file), "--quick"], f"dir '{a_file}' is a file"),
        (["lts", "reconstruct", str(a_file), "--out", str(a_file)], f"dir '{a_file}' is a file"),
        (
            ["lts", "calibrate", "time", str(a_file), "--out", str(missing)],
            f"the folder {missing.parent} does not",
        ),
        (
            ["lts", "calibrate", "time", str(a_file), "--out", str(tmp_path)],
            f"file '{tmp_path}' is a directory",
        ),
        (
            ["rig", "record", "--sim", str(tmp_path), "--out", str(missing)],
            f"the folder {missing.parent} does not",
        ),
    ]
    for (args, says), last in zip(cases, _refused([args for args, _ in cases]), strict=True):
        assert last.startswith("error: Invalid value for ") and says in last, (args, last)


def _refused(command_lines: list[list[str]]) -> list[str]:
    """Each command line's last line of error output, once all have exited with status 2 and no
    traceback (run four at a time)."""
    with ThreadPoolExecutor(4) as pool:
        results = list(pool.map(_run, command_lines))
    for args, result in zip(command_lines, results, strict=True):
        assert result.returncode == 2 and "Traceback" not in result.stderr, (args, result.stderr)
    return [result.stderr.strip().splitlines()[-1] for result in results]


def test_a_bench_budget_out_of_range_stops_before_any_scene_is_simulated(tmp_path: Path) -> None:
    cases = [
        (["lts", "bench", "raster", "--triangles", "-5"], "Invalid value for '--triangles'"),
        (["lts", "bench", "train", "--iterations", "-5", "--out", str(tmp_path)], "--iterations: "),
        (["lts", "bench", "train", "--triangles", "0", "--out", str(tmp_path)], "--triangles: "),
        (["lts", "bench", "train", "--profile", "--iterations", "0", "--out", str(tmp_path)], "iterations"),
    ]
    for (args, says), last in zip(cases, _refused([args for args, _ in cases]), strict=True):
        assert last.startswith("error: ") and says in last, (args, last)
    assert not any(tmp_path.iterdir())  # no scene simulated


def test_every_seed_option_refuses_a_negative_seed_on_the_command_line() -> None:
    """NumPy's generators take no negative seed: a usage error, not their traceback."""
    seeds = [
        (words, p)
        for words, command in _leaves()
        for p in command.params
        if "--seed" in getattr(p, "opts", [])
    ]
    assert len(seeds) >= 5
    unchecked = [" ".join(words) for words, p in seeds if p.min != 0]
    assert not unchecked
    seed, speed = _refused(
        [["lts", "sim", "unused", "--quick", "--seed", "-1"], ["lts", "sim", "unused", "--speed", "0"]]
    )
    assert "Invalid value for '--seed'" in seed
    assert speed == "error: speed_mps: must be positive, got 0.0"
