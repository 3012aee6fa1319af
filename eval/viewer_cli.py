"""``lts view RUN_DIR [--gt GT]``: serve the interactive viewer (:mod:`eval.viewer`) until Ctrl-C
(or SIGTERM)."""

from __future__ import annotations

import signal
import time
from pathlib import Path

import typer

from eval.cli_options import GT_HELP, THRESHOLD_OPTION
from rig.cli_support import console
from rig.native_output import native_output_to_stderr


def view_command(
    run_dir: Path = typer.Argument(
        ..., help="Training run folder (lts train --out) or lts reconstruct output folder (its train/)."
    ),
    gt: Path | None = typer.Option(
        None,
        "--gt",
        help=f"Ground truth: {GT_HELP}. Colours the mesh by its distance to it and shows the F-score.",
    ),
    threshold: float = THRESHOLD_OPTION,
    host: str = typer.Option(
        "127.0.0.1", "--host", help="Address to listen on; 0.0.0.0 opens the viewer to the network."
    ),
    port: int = typer.Option(
        8080, "--port", min=1, max=65535, help="Port to listen on (the next free one if taken)."
    ),
    device: str = typer.Option("cpu", "--device", help="cpu or cuda, where the model renders."),
    render_width: int = typer.Option(
        320,
        "--render-width",
        help="Width in pixels of the model's render of the current view (at most the scene camera's).",
    ),
) -> None:
    """Show a training run in the browser: the exported mesh (photo colours or, with --gt, its
    distance to the ground truth), the raw triangles with their opacity, the ground truth, the
    keyframe cameras with their images, the trajectory, a keyframe's LiDAR points, and the model's
    render of the current viewpoint beside the nearest captured image.

    Prints the URL and serves until Ctrl-C (or SIGTERM). On a robot or server, forward the port over SSH and
    open the URL on your machine: ssh -L 8080:localhost:8080 robot
    """
    if not threshold > 0:
        raise typer.BadParameter(f"must be positive, got {threshold}", param_hint="--threshold")
    if render_width < 1:
        raise typer.BadParameter(f"must be at least 1, got {render_width}", param_hint="--render-width")
    from eval.viewer import Viewer
    from eval.viewer_data import load_viewer_data

    def log(message: str) -> None:
        console.print(f"[dim]{message}[/]", highlight=False)

    _stop_on_signals()
    with native_output_to_stderr():
        data = load_viewer_data(run_dir, gt, device, threshold, log=log)
        viewer = Viewer(data, host, port, render_width)
        try:
            shown = "localhost" if host in ("0.0.0.0", "::", "") else host
            if viewer.port != port:
                log(f"port {port} is taken: using {viewer.port}")
            console.print(f"lts view: {data.run_dir} at http://{shown}:{viewer.port}", highlight=False)
            console.print(
                f"[dim]over SSH: ssh -L {viewer.port}:localhost:{viewer.port} HOST, then open "
                f"http://localhost:{viewer.port} here; Ctrl-C stops[/]",
                highlight=False,
            )
            while True:
                time.sleep(1.0)
        except KeyboardInterrupt:
            console.print("lts view: stopped", highlight=False)
        finally:
            viewer.stop()


def _interrupt(signum: int, frame: object) -> None:
    raise KeyboardInterrupt


def _stop_on_signals() -> None:
    """Ctrl-C and SIGTERM both stop the server cleanly, also where SIGINT arrives ignored (a
    background job of a non-interactive shell inherits that, and Python then never raises
    KeyboardInterrupt)."""
    signal.signal(signal.SIGINT, signal.default_int_handler)
    signal.signal(signal.SIGTERM, _interrupt)
