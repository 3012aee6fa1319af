"""Building blocks of procedural scenes: meshes with a material per face, boxes, joins."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import trimesh
from scipy.spatial.transform import Rotation

from rig.sim.textures import MATERIAL_IDS
from rig.transforms import make_transform


@dataclass
class SceneMesh:
    """A triangle mesh ``(V, 3)``/``(F, 3)`` and the material index of each face ``(F,)``."""

    mesh: trimesh.Trimesh
    face_material: np.ndarray


def join_parts(parts: list[SceneMesh]) -> SceneMesh:
    """One mesh of all ``parts``, their face materials in the same order."""
    mesh = trimesh.util.concatenate([p.mesh for p in parts])
    return SceneMesh(mesh, np.concatenate([p.face_material for p in parts]))


def box(
    size: tuple[float, float, float], centre: tuple[float, float, float], material: str, yaw: float = 0.0
) -> SceneMesh:
    """A closed box ``size`` (x, y, z) centred at ``centre``, turned by ``yaw`` about z."""
    T = make_transform(Rotation.from_euler("z", yaw).as_matrix(), centre)
    mesh = trimesh.creation.box(extents=size, transform=T)
    return SceneMesh(mesh, np.full(len(mesh.faces), MATERIAL_IDS[material]))
