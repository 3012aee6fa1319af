"""The ``office`` preset: furnished, with thin and curved parts and photographic textures, and a
hand-held path that never passes through the furniture."""

from __future__ import annotations

import numpy as np
import open3d as o3d
import pytest

from rig.sim.config import SimConfig
from rig.sim.office import OFFICE_SIZE, office
from rig.sim.scenes import PRESETS
from rig.sim.textures import MATERIAL_IDS, MATERIALS, PHOTOS, material_texture
from rig.sim.trajectories import path_motion


@pytest.fixture(scope="module")
def scene():
    return office(np.random.default_rng([0, 1]))


def test_the_office_is_furnished_within_its_walls(scene):
    lo, hi = scene.mesh.bounds
    assert np.all(lo >= -1e-9) and np.all(hi <= np.array(OFFICE_SIZE) + 1e-9)
    assert len(scene.mesh.faces) > 20_000  # books, chairs, plants: far more than the room's boxes
    used = {MATERIALS[m].name for m in np.unique(scene.face_material)}
    assert set(PHOTOS) <= used  # every photograph is on something


def test_the_office_has_thin_parts(scene):
    """Chair columns, lamp poles, cables and plant stems: parts under 3 cm across."""
    parts = scene.mesh.split(only_watertight=False)
    extents = [np.sort(p.bounding_box_oriented.primitive.extents) for p in parts]
    thin = [e for e in extents if e[1] < 0.03 and e[2] > 0.3]
    assert len(thin) >= 10


def test_the_office_is_the_same_for_a_seed_and_differs_between_seeds(scene):
    again = office(np.random.default_rng([0, 1]))
    other = office(np.random.default_rng([1, 1]))
    assert np.array_equal(scene.mesh.vertices, again.mesh.vertices)
    assert len(other.mesh.vertices) != len(scene.mesh.vertices) or not np.allclose(
        other.mesh.vertices, scene.mesh.vertices
    )


def test_photographs_are_textures_with_real_image_statistics():
    rng = np.random.default_rng(0)
    brick = material_texture(MATERIALS[MATERIAL_IDS["brick_photo"]], rng)
    poster = material_texture(MATERIALS[MATERIAL_IDS["poster_astronaut"]], rng)
    assert brick.shape == poster.shape == (512, 512, 3) and brick.dtype == np.float32
    assert brick.min() >= 0.0 and brick.max() <= 1.0
    # A mirrored photograph tiles without a seam: its opposite borders are the same texels.
    assert np.array_equal(brick[0], brick[-1]) and np.array_equal(brick[:, 0], brick[:, -1])
    assert poster.std(axis=(0, 1)).min() > 0.1  # a colour picture, not a tint


def test_the_hand_held_path_keeps_clear_of_the_furniture(scene):
    preset = PRESETS["office"]
    config = SimConfig(preset="office")
    assert config.carrier == "handheld"
    motion = path_motion(
        np.array(preset.waypoints), 40.0, rng=np.random.default_rng(0), carrier="handheld",
        speed_mps=preset.speed_mps,
    )  # fmt: skip
    positions = motion.positions(np.linspace(0.0, 40.0, 800))
    raycasting = o3d.t.geometry.RaycastingScene()
    vertices, faces = scene.mesh.vertices.astype(np.float32), scene.mesh.faces.astype(np.uint32)
    raycasting.add_triangles(o3d.core.Tensor(vertices), o3d.core.Tensor(faces))
    distance = raycasting.compute_distance(o3d.core.Tensor(positions.astype(np.float32))).numpy()
    assert distance.min() > 0.6
