"""The simulated world: a scene mesh, its appearance and a ray caster, from a preset or a file."""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import trimesh

from rig.mesh_io import load_mesh
from rig.sim.appearance import Appearance, MeshAppearance, ProceduralAppearance
from rig.sim.raycast import Raycaster
from rig.sim.scenes import Preset


@dataclass
class World:
    """A static scene the virtual sensors observe.

    Attributes:
        name: preset name or mesh file name.
        mesh: the geometry (faces indexed by ray hits).
        appearance: colours and reflectivity at hits.
        raycaster: ray casting against ``mesh``.
    """

    name: str
    mesh: trimesh.Trimesh
    appearance: Appearance
    raycaster: Raycaster = field(init=False)

    def __post_init__(self) -> None:
        self.raycaster = Raycaster(self.mesh)


def preset_world(preset: Preset, seed: int) -> World:
    """The procedural scene of ``preset``, its layout and textures seeded by ``seed``."""
    scene = preset.build(np.random.default_rng([seed, 1]))
    return World(preset.name, scene.mesh, ProceduralAppearance(scene.face_material, seed))


def mesh_world(path: str | Path) -> World:
    """A user mesh (PLY/OBJ/GLB..., vertex colours or a texture); raises :class:`InputError` if
    the file cannot be read or holds no triangles."""
    mesh = load_mesh(path)
    return World(Path(path).name, mesh, MeshAppearance(mesh))
