"""``lts``: the offline command line. Each package owns the commands of its stage; this module
mounts them beside the app layer's own (``reconstruct``, ``demo``, ``bench``). Heavy libraries
(torch, open3d) are imported inside the commands so that ``lts --help`` stays fast."""

from __future__ import annotations

import typer

from calib import cli as calib_cli
from eval import weights_cli
from eval.mesh_eval_cli import eval_command
from eval.trajectory_compare_cli import compare_command
from eval.viewer_cli import view_command
from lts import pipeline_cli
from lts.bench.cli import bench_app
from rig import trajectory_cli
from rig.cli_support import HELP_MARKUP, VERSION_OPTION, run_app
from rig.sim import cli as sim_cli
from slam_bridge import cli as slam_cli
from slam_bridge.prepare_cli import prepare_command
from splat.train_cli import train_command

app = typer.Typer(
    rich_markup_mode=HELP_MARKUP,
    name="lts",
    help=(
        "LiDAR-guided Triangle Splatting: turn a camera + LiDAR recording into an accurate, "
        "photo-real triangle mesh (calibrate, map, prepare, train, evaluate)."
    ),
    no_args_is_help=True,
    add_completion=False,
    pretty_exceptions_enable=False,
)
trajectory_cli.app.command("compare")(compare_command)
app.add_typer(trajectory_cli.app, name="trajectory")
app.command("sim")(sim_cli.sim)
app.add_typer(calib_cli.app, name="calibrate")
app.add_typer(slam_cli.app, name="slam")
app.command("prepare")(prepare_command)
app.command("train")(train_command)
app.command("eval")(eval_command)
app.command("view")(view_command)
app.add_typer(weights_cli.app, name="weights")
app.command("reconstruct")(pipeline_cli.reconstruct_command)
app.command("demo")(pipeline_cli.demo_command)
app.add_typer(bench_app, name="bench")


@app.callback()
def _root(
    version: bool = VERSION_OPTION,
) -> None:
    """LiDAR-guided Triangle Splatting toolkit (offline)."""


main = run_app(app, "lts")
