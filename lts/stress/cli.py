"""``lts bench stability [--profile ci|long] [--seed N] [--json]``: the stress suite's counts per
area. The suite (torch, open3d) is imported when the command runs, so that ``lts --help`` stays
fast."""

from __future__ import annotations

import typer

from rig.cli_support import console, emit_json


def bench_stability_command(
    profile: str = typer.Option("ci", "--profile", help="ci (a few seconds) or long (minutes)."),
    seed: int = typer.Option(0, "--seed", min=0, help="Seed of the random cases."),
    json_out: bool = typer.Option(False, "--json", help="Print one JSON object on stdout."),
) -> None:
    """Stress counts per area: cases tried, failures found, non-finite events caught (exit 1 on
    a failure)."""
    from lts.stress.suite import run_stability_suite

    result = run_stability_suite(profile, seed)
    if json_out:
        emit_json(result)
    else:
        for name, area in result["areas"].items():
            console.print(
                f"{name:18s} {area['cases']:6d} cases {area['failures']:4d} failures "
                f"{area['nonfinite_caught']:5d} non-finite caught  {area['seconds']:7.2f} s",
                highlight=False,
            )
            for example in area["examples"]:
                console.print(f"    {example}", highlight=False, markup=False)
    if result["totals"]["failures"]:
        raise SystemExit(1)
