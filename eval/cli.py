"""``lts``: the offline command line.

It lives in ``eval`` because ``eval`` is the last package in the one-way data flow
(rig → calib → slam_bridge → splat → eval) and so the only one allowed to import every other.
Each package owns its own commands; this module only mounts them. Heavy libraries (torch, open3d)
are imported inside the commands so that ``lts --help`` stays fast.
"""

from __future__ import annotations

import typer

from calib import cli as calib_cli
from eval import bench_cli, pipeline_cli
from eval.mesh_eval_cli import eval_command
from eval.stability import bench_stability_command
from rig import trajectory_cli
from rig.cli_support import VERSION_OPTION, run_app
from rig.sim import cli as sim_cli
from slam_bridge import cli as slam_cli
from slam_bridge.prepare_cli import prepare_command
from splat import cli as splat_cli
from splat.train_cli import train_command

app = typer.Typer(
    name="lts",
    help=(
        "LiDAR-guided Triangle Splatting: turn a camera + LiDAR recording into an accurate, "
        "photo-real triangle mesh (calibrate, map, prepare, train, evaluate)."
    ),
    no_args_is_help=True,
    add_completion=False,
    pretty_exceptions_enable=False,
)
app.add_typer(trajectory_cli.app, name="trajectory")
app.command("sim")(sim_cli.sim)
app.command("eval")(eval_command)
app.add_typer(slam_cli.app, name="slam")
app.command("prepare")(prepare_command)
app.command("train")(train_command)
app.command("reconstruct")(pipeline_cli.reconstruct_command)
app.command("demo")(pipeline_cli.demo_command)
app.add_typer(calib_cli.app, name="calibrate")
splat_cli.bench_app.command("train")(bench_cli.bench_train_command)
splat_cli.bench_app.command("ablation")(bench_cli.bench_ablation_command)
splat_cli.bench_app.command("noise")(bench_cli.bench_noise_command)
splat_cli.bench_app.command("stability")(bench_stability_command)
app.add_typer(splat_cli.bench_app, name="bench")


@app.callback()
def _root(
    version: bool = VERSION_OPTION,
) -> None:
    """LiDAR-guided Triangle Splatting toolkit (offline)."""


main = run_app(app, "lts")
