"""Reading triangle meshes with clear errors (missing file, no faces, bad indices, NaN, counts)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import trimesh

from rig.errors import InputError


def _ply_ascii_counts(path: Path) -> None:
    """For an ASCII PLY, the element counts of the header against the data lines.

    trimesh reads an ASCII PLY as one stream of numbers, so a file cut short after its last
    face (or holding more lines than declared) loads without complaint; each element is one
    line in an ASCII PLY, which is what is checked here. Binary PLYs are length-checked by
    trimesh itself.
    """
    with path.open("rb") as fh:
        if fh.readline().strip() != b"ply":
            return  # not a PLY (trimesh will say so)
        elements: list[tuple[str, int]] = []
        ascii_format = False
        for number, raw in enumerate(fh, start=2):
            words = raw.decode("ascii", errors="replace").split()
            if not words:
                continue
            if words[0] == "format":
                ascii_format = len(words) > 1 and words[1] == "ascii"
            elif words[0] == "element" and len(words) >= 3:
                try:
                    elements.append((words[1], int(words[2])))
                except ValueError:
                    raise InputError(
                        f"element count {words[2]!r} is not a number", path=path, line=number, field="header"
                    ) from None
            elif words[0] == "end_header":
                break
        else:
            raise InputError("no end_header line", path=path, field="header")
        if not ascii_format:
            return
        lines = sum(1 for raw in fh if raw.strip())
    declared = sum(count for _, count in elements)
    if lines != declared:
        counts = " + ".join(f"{count} {name}" for name, count in elements)
        raise InputError(
            f"header declares {counts} = {declared} data lines, the file holds {lines} "
            "(truncated or wrong counts)",
            path=path,
            field="element",
        )


def _obj_indices(path: Path) -> None:
    """OBJ vertex lines need 3 coordinates and face indices must name a vertex (1-based; negative
    counts back from the vertices defined so far): trimesh silently rewires an index 0 and keeps
    2-coordinate vertices."""
    try:
        text = path.read_text(errors="replace")
    except OSError as exc:
        raise InputError(f"cannot read mesh ({exc.strerror})", path=path) from None
    vertices = 0
    faces: list[tuple[int, int, int]] = []  # (line, index, vertices defined before it)
    for number, raw in enumerate(text.splitlines(), start=1):
        words = raw.split()
        if not words:
            continue
        if words[0] == "v":
            if len(words) < 4:
                raise InputError(
                    f"vertex has {len(words) - 1} coordinates; expected x y z",
                    path=path,
                    line=number,
                    field="v",
                )
            vertices += 1
        elif words[0] == "f":
            for word in words[1:]:
                try:
                    faces.append((number, int(word.split("/")[0]), vertices))
                except ValueError:
                    raise InputError(
                        f"{word!r} is not a vertex index", path=path, line=number, field="f"
                    ) from None
    for number, index, before in faces:
        if index == 0 or index > vertices or -index > before:
            raise InputError(
                f"index {index} names none of the {vertices} vertices (OBJ indices start at 1)",
                path=path,
                line=number,
                field="f",
            )


#: Triangle mesh files that trimesh reads (its other loaders read point clouds).
MESH_SUFFIXES = (".ply", ".obj", ".stl", ".off", ".glb", ".gltf")


def load_mesh(path: str | Path) -> trimesh.Trimesh:
    """Load a triangle mesh (PLY/OBJ/GLB/...) as one :class:`trimesh.Trimesh`, unprocessed.

    Raises:
        InputError: the file is missing or unreadable, an ASCII PLY's element counts do not match
            its data, an OBJ index names no vertex, there are no faces, faces index missing
            vertices, or vertices are not finite 3-D points.
    """
    path = Path(path)
    if not path.is_file():
        raise InputError("no such mesh file", path=path)
    suffix = path.suffix.lower()
    if suffix not in MESH_SUFFIXES:
        raise InputError(
            f"{suffix or 'no extension'}: not a mesh file type (expected {', '.join(MESH_SUFFIXES)})",
            path=path,
        )
    if suffix == ".ply":
        _ply_ascii_counts(path)
    elif suffix == ".obj":
        _obj_indices(path)
    try:
        mesh = trimesh.load(path, force="mesh", process=False)
    except Exception as exc:  # trimesh raises many exception types for corrupt files
        raise InputError(f"cannot read mesh ({type(exc).__name__}: {exc})", path=path) from None
    if not isinstance(mesh, trimesh.Trimesh) or len(mesh.faces) == 0:
        raise InputError("mesh has no faces", path=path, field="faces")
    vertices = np.asarray(mesh.vertices)
    if vertices.ndim != 2 or vertices.shape[1] != 3:
        raise InputError(f"expected 3-D vertices, got shape {vertices.shape}", path=path, field="vertices")
    faces = np.asarray(mesh.faces)
    if faces.min() < 0 or faces.max() >= len(vertices):
        bad = int(faces.min()) if faces.min() < 0 else int(faces.max())
        raise InputError(
            f"faces index vertex {bad} but the mesh has {len(vertices)} vertices (0 to {len(vertices) - 1})",
            path=path,
            field="faces",
        )
    if not np.all(np.isfinite(vertices)):
        raise InputError("mesh vertices hold NaN or Inf", path=path, field="vertices")
    return mesh
