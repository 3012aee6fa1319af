"""What a surface looks like where a ray hits it: shaded colour and LiDAR reflectivity.

Lighting is fixed in the world (no view dependence), so every view of a point agrees on its
colour, as photometric reconstruction assumes; the ground-truth mesh carries the same colours.
User meshes that bring their own colours (scans, with the light baked in) are not shaded again.
"""

from __future__ import annotations

from typing import Protocol

import numpy as np
import trimesh

from rig.sim.raycast import Hits
from rig.sim.textures import TextureBank

#: Directions to two world-fixed lights and their weights (key light from above, fill light).
LIGHTS = (
    np.array([[0.3, 0.5, 1.0], [-0.7, 0.4, 0.3]])
    / np.linalg.norm([[0.3, 0.5, 1.0], [-0.7, 0.4, 0.3]], axis=1)[:, None]
)
LIGHT_WEIGHTS = np.array([0.6, 0.4])
AMBIENT = 0.45
#: About how many faces a ground-truth mesh is subdivided to at most (for its vertex colours).
MAX_GROUND_TRUTH_FACES = 1_000_000


def shade(normals: np.ndarray) -> np.ndarray:
    """Brightness ``(N,)`` of surfaces with unit ``normals`` ``(N, 3)`` (two-sided Lambert + ambient)."""
    return AMBIENT + (1.0 - AMBIENT) * (np.abs(normals @ LIGHTS.T) @ LIGHT_WEIGHTS)


def luminance(rgb: np.ndarray) -> np.ndarray:
    """Rec. 709 luminance ``(N,)`` of RGB colours ``(N, 3)``."""
    return rgb @ np.array([0.2126, 0.7152, 0.0722])


def _texels(image: np.ndarray, uv: np.ndarray) -> np.ndarray:
    """Nearest texels ``(N, 3)`` of ``image`` ``(H, W, 3)`` at texture coordinates ``(N, 2)``
    (v up, wrapping)."""
    h, w = image.shape[:2]
    col = np.clip(np.floor(uv[:, 0] % 1.0 * w), 0, w - 1).astype(np.int64)
    row = np.clip(np.floor((1.0 - uv[:, 1] % 1.0) * h), 0, h - 1).astype(np.int64)
    return image[row, col]


class Appearance(Protocol):
    """Surface properties of a scene mesh, looked up at ray hits."""

    def colour(self, hits: Hits, footprint_m: np.ndarray) -> np.ndarray:
        """Shaded RGB ``(N, 3)`` in [0, 1] at hits; ``footprint_m`` ``(N,)`` is a sample's size."""
        ...

    def reflectivity(self, hits: Hits) -> np.ndarray:
        """LiDAR reflectivity ``(N,)`` in [0, 1] at hits."""
        ...

    def coloured_mesh(self, mesh: trimesh.Trimesh) -> trimesh.Trimesh:
        """The ground-truth mesh with shaded vertex colours."""
        ...


class ProceduralAppearance:
    """Procedural textures (:class:`TextureBank`) chosen by a material index per face.

    Args:
        face_material: ``(F,)`` material index of each face.
        seed: seeds the textures.
        vertex_spacing_m: edge length the ground-truth mesh is subdivided to, so that its vertex
            colours keep the texture's coarse detail.
    """

    def __init__(self, face_material: np.ndarray, seed: int, vertex_spacing_m: float = 0.1) -> None:
        self.face_material = np.asarray(face_material, dtype=np.int64)
        self.bank = TextureBank(seed)
        self.vertex_spacing_m = vertex_spacing_m

    def colour(self, hits: Hits, footprint_m: np.ndarray) -> np.ndarray:
        albedo = self.bank.sample(self.face_material[hits.face], hits.points, hits.normal, footprint_m)
        return np.clip(albedo * shade(hits.normal)[:, None], 0.0, 1.0)

    def reflectivity(self, hits: Hits) -> np.ndarray:
        return self.bank.reflectivity[self.face_material[hits.face]]

    def coloured_mesh(self, mesh: trimesh.Trimesh) -> trimesh.Trimesh:
        # Large scenes (a street) are subdivided more coarsely, to about MAX_GROUND_TRUTH_FACES
        # (edges end up between half and all of the spacing: 2-8 area / spacing² faces; the street
        # gets about 2 M).
        spacing = max(self.vertex_spacing_m, float(np.sqrt(5.0 * mesh.area / MAX_GROUND_TRUTH_FACES)))
        vertices, faces, parent = trimesh.remesh.subdivide_to_size(
            mesh.vertices, mesh.faces, spacing, max_iter=20, return_index=True
        )
        fine = trimesh.Trimesh(vertices, faces, process=True)
        # Vertices are merged after subdivision: give each vertex the material of a face using it.
        material = np.empty(len(fine.vertices), dtype=np.int64)
        material[fine.faces.reshape(-1)] = np.repeat(self.face_material[parent], 3)
        normals = fine.vertex_normals
        albedo = self.bank.sample(material, fine.vertices, normals, spacing)
        rgb = np.clip(albedo * shade(normals)[:, None], 0.0, 1.0)
        fine.visual.vertex_colors = np.round(rgb * 255).astype(np.uint8)
        return fine


class MeshAppearance:
    """Colours a user mesh carries: per-vertex colours or a UV-mapped texture image.

    Args:
        mesh: the scene mesh as loaded by trimesh (``visual`` holds the colours); a mesh with
            neither is light grey and shaded like the procedural scenes.
    """

    def __init__(self, mesh: trimesh.Trimesh) -> None:
        self.faces = np.asarray(mesh.faces)
        self.image: np.ndarray | None = None
        self.uv: np.ndarray | None = None
        visual = mesh.visual
        material = getattr(visual, "material", None)
        image = getattr(material, "image", None) or getattr(material, "baseColorTexture", None)
        if visual.kind == "texture" and getattr(visual, "uv", None) is not None and image is not None:
            self.image = np.asarray(image.convert("RGB"), dtype=np.float32) / 255.0
            self.uv = np.asarray(visual.uv, dtype=np.float64)
        self.shaded = self.image is None and visual.kind != "vertex"
        if visual.kind == "vertex":
            self.vertex_rgb = np.asarray(visual.vertex_colors, dtype=np.float64)[:, :3] / 255.0
        else:
            self.vertex_rgb = np.full((len(mesh.vertices), 3), 0.7)

    def _interpolate(self, values: np.ndarray, hits: Hits) -> np.ndarray:
        corners = values[self.faces[hits.face]]  # (N, 3, C)
        u, v = hits.bary[:, :1], hits.bary[:, 1:]
        return (1.0 - u - v) * corners[:, 0] + u * corners[:, 1] + v * corners[:, 2]

    def _albedo(self, hits: Hits) -> np.ndarray:
        if self.image is not None and self.uv is not None:
            return _texels(self.image, self._interpolate(self.uv, hits))
        return self._interpolate(self.vertex_rgb, hits)

    def colour(self, hits: Hits, footprint_m: np.ndarray) -> np.ndarray:
        albedo = self._albedo(hits)
        return np.clip(albedo * shade(hits.normal)[:, None], 0.0, 1.0) if self.shaded else albedo

    def reflectivity(self, hits: Hits) -> np.ndarray:
        return 0.2 + 0.7 * luminance(self._albedo(hits))

    def coloured_mesh(self, mesh: trimesh.Trimesh) -> trimesh.Trimesh:
        out = trimesh.Trimesh(mesh.vertices, mesh.faces, process=False)
        rgb = (
            _texels(self.image, self.uv)
            if self.image is not None and self.uv is not None
            else self.vertex_rgb
        )
        if self.shaded:
            rgb = np.clip(rgb * shade(out.vertex_normals)[:, None], 0.0, 1.0)
        out.visual.vertex_colors = np.round(rgb * 255).astype(np.uint8)
        return out
