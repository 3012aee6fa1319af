"""Command-line options that ``lts eval`` and ``lts view`` share (kept free of heavy imports, as
the CLI modules import them at start-up)."""

from __future__ import annotations

import typer

#: What ``--gt`` takes with a run, for the help of ``lts eval`` and ``lts view``.
GT_HELP = (
    "a virtual-rig ground-truth folder (lts sim OUT, OUT/ground_truth or its mesh.ply), aligned by "
    "the keyframe poses, or any other mesh file (PLY/OBJ/GLB) already in the scene's frame"
)
#: ``--threshold`` of ``lts eval`` and ``lts view``.
THRESHOLD_OPTION = typer.Option(0.1, "--threshold", help="F-score distance threshold in metres.")
