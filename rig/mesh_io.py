"""Reading triangle meshes with clear errors (missing file, no faces, bad indices, NaN)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import trimesh

from rig.errors import InputError


def load_mesh(path: str | Path) -> trimesh.Trimesh:
    """Load a triangle mesh (PLY/OBJ/GLB/...) as one :class:`trimesh.Trimesh`, unprocessed.

    Raises:
        InputError: the file is missing or unreadable, has no faces, faces index missing
            vertices, or vertices hold NaN/Inf.
    """
    path = Path(path)
    if not path.is_file():
        raise InputError("no such mesh file", path=path)
    try:
        mesh = trimesh.load(path, force="mesh", process=False)
    except Exception as exc:  # trimesh raises many exception types for corrupt files
        raise InputError(f"cannot read mesh ({type(exc).__name__}: {exc})", path=path) from None
    if not isinstance(mesh, trimesh.Trimesh) or len(mesh.faces) == 0:
        raise InputError("mesh has no faces", path=path, field="faces")
    faces = np.asarray(mesh.faces)
    if faces.min() < 0 or faces.max() >= len(mesh.vertices):
        raise InputError(
            f"faces index vertex {int(faces.max())} but the mesh has {len(mesh.vertices)} vertices",
            path=path,
            field="faces",
        )
    if not np.all(np.isfinite(mesh.vertices)):
        raise InputError("mesh vertices hold NaN or Inf", path=path, field="vertices")
    return mesh
