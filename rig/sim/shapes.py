"""Building blocks of procedural scenes: meshes with a material per face; boxes, cylinders,
ellipsoids and solids of revolution; joins and placement."""

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


def solid(mesh: trimesh.Trimesh, material: str, transform: np.ndarray | None = None) -> SceneMesh:
    """``mesh`` of one ``material``, moved by ``transform`` ``(4, 4)`` when given."""
    if transform is not None:
        mesh = mesh.copy()
        mesh.apply_transform(transform)
    return SceneMesh(mesh, np.full(len(mesh.faces), MATERIAL_IDS[material]))


def cylinder(
    radius: float, height: float, base: tuple[float, float, float], material: str, sections: int = 24
) -> SceneMesh:
    """An upright closed cylinder standing on ``base`` (the centre of its bottom disc)."""
    mesh = trimesh.creation.cylinder(radius=radius, height=height, sections=sections)
    return solid(mesh, material, make_transform(np.eye(3), np.add(base, (0.0, 0.0, height / 2))))


def ellipsoid(
    radii: tuple[float, float, float], transform: np.ndarray, material: str, subdivisions: int = 2
) -> SceneMesh:
    """A closed ellipsoid with semi-axes ``radii`` (its own x, y, z), placed by ``transform``."""
    mesh = trimesh.creation.icosphere(subdivisions=subdivisions)
    mesh.apply_scale(radii)
    return solid(mesh, material, transform)


def revolved(
    profile: list[tuple[float, float]], base: tuple[float, float, float], material: str, sections: int = 32
) -> SceneMesh:
    """A closed solid of revolution about the vertical axis through ``base``: ``profile`` is its
    outline as (radius, height) points of a closed polygon (a pot's, a lampshade's)."""
    outline = np.asarray([*profile, profile[0]], dtype=np.float64)
    mesh = trimesh.creation.revolve(outline, sections=sections)
    return solid(mesh, material, make_transform(np.eye(3), base))


def curved_panel(
    radii: tuple[float, float],
    height: float,
    arc: tuple[float, float],
    base: tuple[float, float, float],
    material: str,
    sections: int = 12,
) -> SceneMesh:
    """A closed curved slab (a backrest): the part of a ring of ``radii`` (inner, outer) round the
    vertical axis through ``base`` between the angles ``arc`` (radians from +x), ``height`` tall."""
    angle = np.linspace(*arc, sections + 1)
    ring = [(r * np.cos(angle), r * np.sin(angle)) for r in radii]
    corners = [(*ring[0], 0.0), (*ring[1], 0.0), (*ring[1], height), (*ring[0], height)]
    vertices = np.stack([np.column_stack([x, y, np.full_like(x, z)]) for x, y, z in corners], axis=1).reshape(
        -1, 3
    )  # 4 corners per angle
    quads = []
    for k in range(sections):
        a, b = 4 * k, 4 * (k + 1)
        quads += [(a + c, b + c, b + (c + 1) % 4, a + (c + 1) % 4) for c in range(4)]
    quads += [(0, 3, 2, 1), (4 * sections, 4 * sections + 1, 4 * sections + 2, 4 * sections + 3)]
    q = np.asarray(quads)
    mesh = trimesh.Trimesh(vertices, np.concatenate([q[:, [0, 1, 2]], q[:, [0, 2, 3]]]), process=True)
    mesh.fix_normals()
    return solid(mesh, material, make_transform(np.eye(3), base))


def placed(parts: list[SceneMesh], xy: tuple[float, float], yaw: float, z: float = 0.0) -> list[SceneMesh]:
    """``parts`` built in a local frame, turned by ``yaw`` about z and moved to ``xy``, ``z`` up."""
    T = make_transform(Rotation.from_euler("z", yaw).as_matrix(), (*xy, z))
    return [SceneMesh(p.mesh.copy().apply_transform(T), p.face_material) for p in parts]


def shell(
    size: tuple[float, float, float], walls: str, floor: str = "tiles", ceiling: str = "ceiling"
) -> SceneMesh:
    """Inward-facing box from (0, 0, 0) to ``size``: floor, ceiling and four walls."""
    outward = trimesh.creation.box(extents=size, transform=make_transform(np.eye(3), np.asarray(size) / 2))
    mesh = trimesh.Trimesh(outward.vertices, outward.faces[:, ::-1])  # reversed winding: normals point in
    nz = mesh.face_normals[:, 2]
    material = np.where(
        nz > 0.5, MATERIAL_IDS[floor], np.where(nz < -0.5, MATERIAL_IDS[ceiling], MATERIAL_IDS[walls])
    )
    return SceneMesh(mesh, material)
