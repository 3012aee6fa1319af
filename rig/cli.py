"""``rig``: the on-robot command line (record, inspect and replay sessions)."""

from __future__ import annotations

import typer

from rig.cli_support import run_app, version_callback

app = typer.Typer(
    name="rig",
    help="On-robot tools: record time-stamped camera + LiDAR sessions and inspect them.",
    no_args_is_help=True,
    add_completion=False,
    pretty_exceptions_enable=False,
)


@app.callback()
def _root(
    version: bool = typer.Option(
        False,
        "--version",
        callback=version_callback,
        is_eager=True,
        help="Print the version and exit.",
    ),
) -> None:
    """On-robot tools: record time-stamped camera + LiDAR sessions and inspect them."""


main = run_app(app, "rig")
