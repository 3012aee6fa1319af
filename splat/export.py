"""The trained triangles as meshes: a render mesh (PLY/OBJ/GLB) and a welded collision mesh.

The render mesh keeps every triangle independent (``3F`` vertices) with its per-vertex colours:
that is what the rasteriser drew; with camera-only flags, its PLY holds them as the face property
``camera_only`` (1: no LiDAR return near the triangle — geometry from the images alone, or the
floor filled where the LiDAR never looked — lower confidence). The collision mesh keeps only the
triangles a physics engine should collide with — opaque, seen from a training view or lying on
the floor where no camera looked, not degenerate — welds their corners into one connected surface
and drops duplicate faces. It is written as PLY (the toolkit's mesh format) and OBJ (the format
pybullet reads).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np
import torch
import trimesh
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components
from scipy.spatial import cKDTree

from rig.atomic_file import write_atomic
from rig.errors import InputError
from splat.model import TriangleModel

RENDER_FILES = ("mesh.ply", "mesh.obj", "mesh.glb")
COLLISION_FILES = ("collision.ply", "collision.obj")


@dataclass(frozen=True)
class ExportResult:
    """What :func:`export_mesh` wrote.

    Attributes:
        paths: the files written (render PLY/OBJ/GLB, then collision PLY/OBJ).
        n_triangles: triangles in the render mesh (all of the model's).
        n_collision_triangles: triangles in the collision mesh.
        n_removed_transparent: triangles left out of the collision mesh for opacity < min_opacity.
        n_removed_unseen: of the rest, those that dominated no pixel of any training view and do
            not lie on the floor.
        n_kept_unseen_floor: opaque triangles no training view saw, kept as floor.
        n_removed_degenerate: of the rest, those thinner than the weld distance (after welding).
        n_removed_duplicate: of the rest, repeats of a face already kept (same corners, any order).
        n_collision_vertices: vertices of the welded collision mesh.
    """

    paths: list[Path]
    n_triangles: int
    n_collision_triangles: int
    n_removed_transparent: int
    n_removed_unseen: int
    n_kept_unseen_floor: int
    n_removed_degenerate: int
    n_removed_duplicate: int
    n_collision_vertices: int


def export_mesh(
    model: TriangleModel,
    out_dir: Path,
    *,
    seen: torch.Tensor | None = None,
    floor: np.ndarray | None = None,
    camera_only: np.ndarray | None = None,
    min_opacity: float = 0.5,
    weld_m: float = 1e-3,
) -> ExportResult:
    """Write ``out_dir/{mesh.ply, mesh.obj, mesh.glb, collision.ply, collision.obj}`` atomically.

    Args:
        model: the trained triangles (``F`` of them).
        out_dir: created if missing.
        seen: ``(F,)`` bool, True where the triangle dominated at least one pixel of a training
            view; None keeps all triangles.
        floor: ``(F,)`` bool, True where a triangle lies on the floor: kept in the collision
            mesh also where no view sees it (the completed floor); None: none.
        camera_only: ``(F,)`` bool, True where no LiDAR return backs the triangle: flagged in the
            render PLY; None: no flags.
        min_opacity: triangles with a lower activated opacity are left out of the collision mesh.
        weld_m: collision-mesh corners closer than this (metres) become one vertex.

    Raises:
        InputError: ``seen`` has the wrong shape, ``min_opacity`` or ``weld_m`` is out of range,
            or no triangle is left for the collision mesh (nothing is written then).
    """
    if not 0.0 <= min_opacity <= 1.0:
        raise InputError(f"expected an opacity in [0, 1], got {min_opacity}", field="min_opacity")
    if not weld_m >= 0.0:
        raise InputError(f"expected a distance >= 0, got {weld_m}", field="weld_m")
    triangles = model.params["vertices"].detach().cpu().double().numpy()
    colors = model.triangle_colors().detach().cpu().numpy()
    opacity = model.triangle_opacity().detach().cpu().numpy()
    n = len(triangles)
    keep_seen = np.ones(n, dtype=bool) if seen is None else _seen_mask(seen, n)
    for name, flags in (("floor", floor), ("camera_only", camera_only)):
        if flags is not None and np.shape(flags) != (n,):
            raise InputError(f"expected ({n},) flags, got {np.shape(flags)}", field=name)
    unseen_floor = np.zeros(n, dtype=bool) if floor is None else np.asarray(floor, dtype=bool) & ~keep_seen
    keep_seen = keep_seen | unseen_floor  # a new array: the mask may share the caller's tensor

    opaque = opacity >= min_opacity
    out_dir = Path(out_dir)
    collision, n_degenerate, n_duplicate = _collision_mesh(
        triangles[opaque & keep_seen], weld_m, out_dir / COLLISION_FILES[0]
    )
    out_dir.mkdir(parents=True, exist_ok=True)
    render = _render_mesh(triangles, colors)
    if camera_only is not None:
        render.face_attributes["camera_only"] = np.asarray(camera_only, dtype=np.uint8)
    paths = [out_dir / name for name in RENDER_FILES + COLLISION_FILES]
    blobs = [
        render.export(file_type="ply", encoding="binary"),
        render.export(file_type="obj", include_normals=False),
        render.export(file_type="glb"),
        collision.export(file_type="ply", encoding="binary"),
        collision.export(file_type="obj", include_normals=False),
    ]
    for path, blob in zip(paths, blobs, strict=True):
        write_atomic(path, blob)
    return ExportResult(
        paths=paths,
        n_triangles=n,
        n_collision_triangles=len(collision.faces),
        n_removed_transparent=int((~opaque).sum()),
        n_removed_unseen=int((opaque & ~keep_seen).sum()),
        n_kept_unseen_floor=int((opaque & unseen_floor).sum()),
        n_removed_degenerate=n_degenerate,
        n_removed_duplicate=n_duplicate,
        n_collision_vertices=len(collision.vertices),
    )


def _seen_mask(seen: torch.Tensor, n: int) -> np.ndarray:
    """``(F,)`` bool array from the ``seen`` tensor, checked against the model's triangle count."""
    if tuple(seen.shape) != (n,) or seen.dtype != torch.bool:
        raise InputError(
            f"expected a bool tensor of shape ({n},), got {seen.dtype} {tuple(seen.shape)}", field="seen"
        )
    return seen.detach().cpu().numpy()


def _render_mesh(triangles: np.ndarray, colors: np.ndarray) -> trimesh.Trimesh:
    """Independent triangles ``(F, 3, 3)`` with per-vertex RGB ``(F, 3, 3)`` in [0, 1] as a mesh of
    ``3F`` vertices with uint8 vertex colours."""
    n = len(triangles)
    rgb = np.round(colors.reshape(3 * n, 3) * 255).clip(0, 255).astype(np.uint8)
    return trimesh.Trimesh(
        vertices=triangles.reshape(3 * n, 3),
        faces=np.arange(3 * n).reshape(n, 3),
        vertex_colors=rgb,
        process=False,
    )


def _collision_mesh(triangles: np.ndarray, weld_m: float, path: Path) -> tuple[trimesh.Trimesh, int, int]:
    """The welded mesh of ``triangles`` ``(K, 3, 3)``, with the counts of degenerate and duplicate
    faces it dropped.

    Raises:
        InputError: no triangle is left (naming ``path``, the collision file it was meant for).
    """
    if len(triangles) == 0:
        raise InputError("no triangle is left for the collision mesh (all transparent or unseen)", path=path)
    vertices, faces = _weld(triangles.reshape(-1, 3), weld_m)
    faces = faces.reshape(-1, 3)
    # Degenerate: thinner than the weld distance (which includes two corners welded into one). At
    # that scale a corner is "the same point" as the opposite edge: there is no area to collide with.
    solid = faces[trimesh.triangles.nondegenerate(vertices[faces], height=weld_m)]
    _, first = np.unique(np.sort(solid, axis=1), axis=0, return_index=True)
    unique = solid[np.sort(first)]
    if len(unique) == 0:
        raise InputError(
            "no triangle is left for the collision mesh (the opaque, seen ones are all degenerate)",
            path=path,
        )
    mesh = trimesh.Trimesh(vertices, unique, process=False)
    mesh.remove_unreferenced_vertices()
    return mesh, len(faces) - len(solid), len(solid) - len(unique)


def _weld(points: np.ndarray, weld_m: float) -> tuple[np.ndarray, np.ndarray]:
    """Merge points ``(P, 3)`` closer than ``weld_m`` (transitively) into one vertex each.

    A KD-tree's pairs within ``weld_m`` joined into connected components weld every such pair.
    Rounding to a grid (trimesh ``merge_vertices`` with ``digits_vertex``) would not: two points a
    nanometre apart on either side of a grid line stay apart. Each cluster keeps the position of
    its lowest-index member, so welded vertices are vertices of the model.

    Returns:
        vertices ``(V, 3)`` and, for each input point, its vertex index ``(P,)``.
    """
    pairs = cKDTree(points).query_pairs(weld_m, output_type="ndarray")
    graph = coo_matrix((np.ones(len(pairs)), (pairs[:, 0], pairs[:, 1])), shape=(len(points),) * 2)
    _, labels = connected_components(graph, directed=False)
    _, representative, index = np.unique(labels, return_index=True, return_inverse=True)
    return points[representative], index
