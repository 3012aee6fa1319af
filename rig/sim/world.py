"""The simulated world: a scene mesh, its appearance, moving objects, sky and a ray caster."""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import trimesh

from rig.mesh_io import load_mesh
from rig.sim.appearance import Appearance, MeshAppearance, ProceduralAppearance
from rig.sim.movers import Mover, MovingRaycaster
from rig.sim.scenes import Preset

#: Sky colours (linear RGB in [0, 1]) at the horizon and the zenith; the sky blends between them.
SKY_HORIZON = np.array([0.82, 0.86, 0.90])
SKY_ZENITH = np.array([0.36, 0.54, 0.82])


@dataclass
class World:
    """The scene the virtual sensors observe.

    Attributes:
        name: preset name or mesh file name.
        mesh: the static geometry (faces indexed by ray hits; the ground truth).
        appearance: colours and reflectivity at hits (static faces, then the movers' faces).
        movers: objects that move during the run (not in ``mesh``).
        sky: rays that miss everything see the sky (open scenes); otherwise black.
        raycaster: ray casting against ``mesh`` and the movers at each ray's time.
    """

    name: str
    mesh: trimesh.Trimesh
    appearance: Appearance
    movers: tuple[Mover, ...] = ()
    sky: bool = False
    raycaster: MovingRaycaster = field(init=False)

    def __post_init__(self) -> None:
        self.raycaster = MovingRaycaster(self.mesh, self.movers)


def sky_colour(directions: np.ndarray) -> np.ndarray:
    """RGB ``(N, 3)`` of the sky seen along unit world ``directions`` ``(N, 3)`` (z up): a smooth
    gradient from a pale horizon to a blue zenith (below the horizon, the horizon's colour)."""
    up = np.clip(directions[:, 2], 0.0, 1.0)[:, None] ** 0.6
    return (1.0 - up) * SKY_HORIZON + up * SKY_ZENITH


def preset_world(preset: Preset, seed: int, traffic: bool, speed_mps: float) -> World:
    """The procedural scene of ``preset`` and, with ``traffic``, its movers (for a robot at
    ``speed_mps``); layout and textures seeded by ``seed``."""
    scene = preset.build(np.random.default_rng([seed, 1]))
    rng = np.random.default_rng([seed, 3])
    movers = tuple(preset.movers(rng, speed_mps)) if preset.movers and traffic else ()
    material = np.concatenate([scene.face_material, *(m.face_material for m in movers)])
    return World(preset.name, scene.mesh, ProceduralAppearance(material, seed), movers, preset.sky)


def mesh_world(path: str | Path) -> World:
    """A user mesh (PLY/OBJ/GLB..., vertex colours or a texture); raises :class:`InputError` if
    the file cannot be read or holds no triangles."""
    mesh = load_mesh(path)
    return World(Path(path).name, mesh, MeshAppearance(mesh))
