"""What the commands that read a training run (``lts eval RUN``, ``lts view``) accept as ``RUN``
and ``--gt``, resolved once, with a one-line error naming the path when it is neither.

- ``RUN``: a training run folder (``lts train --out``: ``model.pt`` and ``run.json``) or an
  ``lts reconstruct --out`` folder, whose run is ``train/``.
- ``--gt``: a folder, the virtual-rig ground truth (``lts sim OUT/ground_truth`` or ``OUT``), which
  :func:`eval.ground_truth.load_ground_truth` aligns to the scene by the keyframe poses (so is
  that folder's own ``mesh.ply``); or any other mesh file (PLY/OBJ/GLB), taken as already in the
  scene's frame (a survey of the site) and used as it is.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

from eval.ground_truth import ground_truth_dir, ground_truth_mesh_file, is_rig_ground_truth_mesh
from rig.errors import InputError
from splat import run_dir as layout

#: Where ``lts reconstruct --out OUT`` trains (OUT/train).
RECONSTRUCT_RUN = "train"


@dataclass(frozen=True)
class RunInputs:
    """A resolved ``RUN`` and ``--gt``.

    Attributes:
        run_dir: the training run folder (holds ``model.pt``).
        gt: the ground-truth folder (holding ``mesh.ply`` and ``trajectory.tum``) or mesh file;
            ``None`` without ``--gt``.
    """

    run_dir: Path
    gt: Path | None


def resolve_run_dir(path: str | Path) -> Path:
    """The training run ``path`` names: ``path`` itself when it holds ``model.pt``, its ``train/``
    when it is an ``lts reconstruct`` folder."""
    path = Path(path)
    for candidate in (path, path / RECONSTRUCT_RUN):
        if layout.model_path(candidate).is_file():
            return candidate
    if not path.is_dir():
        raise InputError("no such run folder", path=path)
    raise InputError(
        f"not a training run folder: expected {layout.MODEL} and {layout.RUN_INFO} (lts train --out) or "
        f"an lts reconstruct --out folder with {RECONSTRUCT_RUN}/{layout.MODEL}",
        path=path,
    )


def resolve_gt(path: str | Path) -> Path:
    """The ground truth ``--gt`` names: a virtual-rig ground-truth folder (``path`` or its
    ``ground_truth/``) or a mesh file."""
    path = Path(path)
    if path.is_dir():
        return ground_truth_dir(path)
    if not path.exists():
        raise InputError("no such ground-truth folder or mesh file", path=path, field="--gt")
    if is_rig_ground_truth_mesh(path):
        return path.parent
    return ground_truth_mesh_file(path)


def resolve_run_inputs(run: str | Path, gt: str | Path | None = None) -> RunInputs:
    """Resolve ``RUN`` and ``--gt`` (see the module docstring); raises
    :class:`~rig.errors.InputError` naming the path that is neither."""
    return RunInputs(resolve_run_dir(run), None if gt is None else resolve_gt(gt))
