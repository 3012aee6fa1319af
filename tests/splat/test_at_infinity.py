"""Camera-only cells in front of the sky are left to the background; cells on a textured wall stay."""

from __future__ import annotations

import numpy as np

from rig.transforms import make_transform
from splat.at_infinity import explained_at_infinity
from splat.raster.scenes import pinhole

CAMERA = pinhole(96, 64, fov_deg=70.0)
WALL_Z_M = 10.0  # a wall facing the cameras, 10 m ahead, below the horizon (camera y points down)


def street_images(offsets_x: np.ndarray) -> tuple[list[np.ndarray], np.ndarray]:
    """Images ``(H, W, 3)`` uint8 of cameras moved along x by ``offsets_x`` (m), looking along +z: a
    checkered wall (0.4 m squares) where rays meet ``z = WALL_Z_M`` below y = 0, above it a sky whose
    colour depends on the direction alone; and the poses ``(K, 4, 4)``."""
    v, u = np.mgrid[0 : CAMERA.height, 0 : CAMERA.width]
    pixels = np.stack([u.ravel(), v.ravel()], axis=1).astype(np.float64)
    rays = CAMERA.unproject(pixels)  # (H·W, 3) at z = 1
    directions = rays / np.linalg.norm(rays, axis=1, keepdims=True)
    down = directions[:, 1]
    sky = np.stack([0.4 - 0.3 * down, 0.6 - 0.2 * down, np.full_like(down, 0.9)], axis=1)
    images, poses = [], []
    for x in offsets_x:
        hit = np.array([x, 0.0, 0.0]) + rays * WALL_Z_M
        checker = (np.floor(hit[:, 0] / 0.4) + np.floor(hit[:, 1] / 0.4)) % 2
        wall = np.where(checker[:, None] > 0, [0.7, 0.3, 0.2], [0.3, 0.2, 0.1])
        rgb = np.where((hit[:, 1] > 0)[:, None], wall, sky)
        images.append((255 * rgb.reshape(CAMERA.height, CAMERA.width, 3)).round().astype(np.uint8))
        poses.append(make_transform(np.eye(3), np.array([x, 0.0, 0.0])))
    return images, np.stack(poses)


def test_cells_in_front_of_the_sky_are_explained_at_infinity_and_cells_on_the_wall_are_not():
    images, poses = street_images(np.linspace(0.0, 2.0, 6))
    along = np.linspace(-0.6, 2.6, 9)
    on_wall = np.stack([along, np.full_like(along, 1.5), np.full_like(along, WALL_Z_M)], axis=1)
    before_sky = np.stack([along, np.full_like(along, -2.0), np.full_like(along, WALL_Z_M)], axis=1)
    assert not explained_at_infinity(on_wall, CAMERA, images, poses).any()
    assert explained_at_infinity(before_sky, CAMERA, images, poses).all()
    # Seen by fewer than three keyframes: no verdict, the cell stays.
    assert not explained_at_infinity(before_sky, CAMERA, images[:2], poses[:2]).any()
    assert explained_at_infinity(np.zeros((0, 3)), CAMERA, images, poses).shape == (0,)
