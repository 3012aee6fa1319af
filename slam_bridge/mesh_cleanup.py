"""Cleaning a mapper's mesh into a consistent triangle surface."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import trimesh
from scipy.spatial import cKDTree

from rig.errors import InputError

#: Faces whose area is below this (m²) are degenerate.
MIN_FACE_AREA_M2 = 1e-12


@dataclass(frozen=True)
class CleanupReport:
    """What cleaning removed or changed."""

    unused_vertices: int
    degenerate_faces: int
    duplicate_faces: int
    flipped_faces: int


def check_faces(vertices: np.ndarray, faces: np.ndarray, path: str | None = None) -> None:
    """Raise :class:`InputError` if faces ``(F, 3)`` index vertices ``(V, 3)`` that do not exist."""
    if faces.size and (faces.min() < 0 or faces.max() >= len(vertices)):
        bad = int(np.flatnonzero((faces < 0).any(axis=1) | (faces >= len(vertices)).any(axis=1))[0])
        raise InputError(
            f"face {bad} indexes vertex {faces[bad].tolist()} but there are only {len(vertices)} vertices",
            path=path,
            field="faces",
        )
    if not np.all(np.isfinite(vertices)):
        raise InputError("vertex coordinates hold NaN or Inf", path=path, field="vertex")


def clean_mesh(
    vertices: np.ndarray, faces: np.ndarray, viewpoints: np.ndarray | None = None
) -> tuple[trimesh.Trimesh, CleanupReport]:
    """Drop unused vertices and degenerate/duplicate faces, and orient faces consistently.

    Args:
        vertices: ``(V, 3)`` positions.
        faces: ``(F, 3)`` vertex indices.
        viewpoints: optional ``(P, 3)`` sensor positions (the trajectory). After winding is made
            consistent within each connected component, a component whose faces mostly face away
            from the nearest viewpoint is flipped, so normals point towards the free space the
            sensor moved through.

    Returns:
        The cleaned mesh and a report of what changed.
    """
    vertices = np.asarray(vertices, dtype=np.float64)
    faces = np.asarray(faces, dtype=np.int64).reshape(-1, 3)
    check_faces(vertices, faces)
    repeated_index = (
        (faces[:, 0] == faces[:, 1]) | (faces[:, 1] == faces[:, 2]) | (faces[:, 0] == faces[:, 2])
    )
    tri = vertices[faces]
    area = 0.5 * np.linalg.norm(np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]), axis=1)
    degenerate = repeated_index | (area < MIN_FACE_AREA_M2)
    faces = faces[~degenerate]
    _, first = np.unique(np.sort(faces, axis=1), axis=0, return_index=True)
    duplicates = len(faces) - len(first)
    faces = faces[np.sort(first)]
    used = np.unique(faces)
    remap = np.full(len(vertices), -1, dtype=np.int64)
    remap[used] = np.arange(len(used))
    mesh = trimesh.Trimesh(vertices[used], remap[faces], process=False)
    before = mesh.faces.copy()
    trimesh.repair.fix_winding(mesh)
    if viewpoints is not None and len(viewpoints):
        _face_components_towards(mesh, np.asarray(viewpoints, dtype=np.float64))
    flipped = int(np.sum(np.any(mesh.faces != before, axis=1)))
    report = CleanupReport(len(vertices) - len(used), int(degenerate.sum()), int(duplicates), flipped)
    return mesh, report


def _face_components_towards(mesh: trimesh.Trimesh, viewpoints: np.ndarray) -> None:
    """Flip each connected component whose faces mostly face away from the nearest viewpoint."""
    _, nearest = cKDTree(viewpoints).query(mesh.triangles_center)
    facing = np.einsum("ij,ij->i", mesh.face_normals, viewpoints[nearest] - mesh.triangles_center) > 0
    faces = mesh.faces.copy()
    for component in trimesh.graph.connected_components(mesh.face_adjacency, nodes=np.arange(len(faces))):
        if facing[component].mean() < 0.5:
            faces[component] = faces[component][:, ::-1]
    mesh.faces = faces
