"""Ray casting against a triangle mesh with open3d's ``RaycastingScene`` (one call per batch)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import trimesh

from rig.mesh_rays import mesh_raycaster
from rig.open3d_lite import o3d


@dataclass
class Hits:
    """Where ``N`` rays hit the mesh.

    Attributes:
        distance: ``(N,)`` distance along the (unit) ray; ``inf`` where it missed.
        face: ``(N,)`` int64 index of the face hit; -1 where it missed.
        bary: ``(N, 2)`` barycentric coordinates (of vertices 1 and 2) of the hit in the face.
        normal: ``(N, 3)`` unit normal of the face hit.
        points: ``(N, 3)`` hit points in the world (NaN where missed).
    """

    distance: np.ndarray
    face: np.ndarray
    bary: np.ndarray
    normal: np.ndarray
    points: np.ndarray

    @property
    def hit(self) -> np.ndarray:
        """``(N,)`` bool: the ray hit the mesh."""
        return self.face >= 0

    def subset(self, mask: np.ndarray) -> Hits:
        """The hits selected by a boolean mask or index array."""
        return Hits(
            self.distance[mask], self.face[mask], self.bary[mask], self.normal[mask], self.points[mask]
        )


class Raycaster:
    """A static triangle mesh prepared for ray casting.

    Args:
        mesh: the scene; its faces are what :attr:`Hits.face` indexes.
    """

    def __init__(self, mesh: trimesh.Trimesh) -> None:
        self._scene = mesh_raycaster(mesh)

    def cast(self, origins: np.ndarray, directions: np.ndarray) -> Hits:
        """Cast rays from ``origins`` ``(N, 3)`` (or one ``(3,)``) along unit ``directions`` ``(N, 3)``."""
        directions = np.asarray(directions, dtype=np.float64)
        origins = np.broadcast_to(np.asarray(origins, dtype=np.float64), directions.shape)
        rays = np.concatenate([origins, directions], axis=1).astype(np.float32)
        result = self._scene.cast_rays(o3d.core.Tensor(rays))
        distance = result["t_hit"].numpy().astype(np.float64)
        face = result["primitive_ids"].numpy().astype(np.int64)
        missed = ~np.isfinite(distance)
        face[missed] = -1
        points = origins + directions * np.where(missed, np.nan, distance)[:, None]
        return Hits(
            distance,
            face,
            result["primitive_uvs"].numpy().astype(np.float64),
            result["primitive_normals"].numpy().astype(np.float64),
            points,
        )
