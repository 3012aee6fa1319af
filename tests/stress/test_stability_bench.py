"""lts.stress.suite.run_stability_suite: the numbers `lts bench stability --json` will print."""

from __future__ import annotations

import json

import pytest

from lts.stress.suite import PROFILES, run_stability_suite
from rig.errors import InputError


def test_ci_profile_runs_every_area_and_finds_no_failures() -> None:
    result = run_stability_suite("ci", seed=1)
    json.dumps(result)  # plain data, ready for --json
    assert set(result["areas"]) == set(PROFILES["ci"])
    for name, area in result["areas"].items():
        assert area["cases"] == PROFILES["ci"][name], name
        assert area["failures"] == 0, (name, area["examples"])
    totals = result["totals"]
    assert totals["cases"] == sum(PROFILES["ci"].values()) and totals["failures"] == 0
    # NaN/Inf and other invalid inputs are fed in on purpose and must be caught.
    for name in ("raster_nonfinite", "geometry", "readers"):
        assert result["areas"][name]["nonfinite_caught"] > 0, name


def test_unknown_profile() -> None:
    with pytest.raises(InputError, match="unknown profile"):
        run_stability_suite("medium")


def test_bench_stability_command_prints_one_json_object() -> None:
    """The command the lead mounts as ``lts bench stability`` (here on a bare Typer app)."""
    import typer
    from typer.testing import CliRunner

    from lts.stress.cli import bench_stability_command

    app = typer.Typer()
    app.command("stability")(bench_stability_command)
    app.command("unused")(lambda: None)  # two commands: the name is required, as under `lts bench`
    result = CliRunner().invoke(app, ["stability", "--seed", "2", "--json"])
    assert result.exit_code == 0, result.output
    report = json.loads(result.stdout.strip().splitlines()[-1])
    assert report["profile"] == "ci" and report["totals"]["failures"] == 0
