"""Plane-sweep stereo above the LiDAR's reach: depths of a textured wall, nothing on a blank sky."""

from __future__ import annotations

import cv2
import numpy as np

from rig.camera import CameraModel
from splat.plane_sweep import (
    CELL_PX,
    SWEEP_FAR_M,
    SWEEP_NEAR_M,
    SWEEP_PLANES,
    _grey,
    keyframe_sweeps,
    sweep_depth,
    swept_cells,
    without_fattening,
)
from splat.upright_planes import UprightPlanes

CAMERA = CameraModel("pinhole", 160, 96, [[120, 0, 79.5], [0, 120, 47.5], [0, 0, 1]], [])
WALL_Z = 12.0


def _texture(seed: int = 0) -> np.ndarray:
    """A grey-level texture ``(1024, 1024)`` in [0, 1] with detail at a few pixels' scale."""
    noise = np.random.default_rng(seed).random((1024, 1024)).astype(np.float32)
    return cv2.GaussianBlur(noise, (0, 0), 2.0)


def _wall_image(texture: np.ndarray, centre: np.ndarray) -> np.ndarray:
    """RGB ``(H, W, 3)`` uint8 of a wall in the plane z = WALL_Z (texture 1 px per 5 cm) seen by a
    camera at ``centre`` ``(3,)`` looking along +z."""
    v, u = np.mgrid[0 : CAMERA.height, 0 : CAMERA.width].astype(np.float32)
    reach = WALL_Z - centre[2]
    x = centre[0] + (u - CAMERA.cx) / CAMERA.fx * reach
    y = centre[1] + (v - CAMERA.cy) / CAMERA.fy * reach
    grey = cv2.remap(
        texture, (x / 0.05 + 512).astype(np.float32), (y / 0.05 + 512).astype(np.float32), cv2.INTER_LINEAR
    )
    return np.repeat((grey * 255).astype(np.uint8)[..., None], 3, axis=2)


def _pose(centre: np.ndarray) -> np.ndarray:
    T = np.eye(4)
    T[:3, 3] = centre
    return T


def test_a_textured_wall_gets_its_depth_and_a_blank_one_none() -> None:
    texture = _texture()
    centres = [np.array([-1.0, 0.0, 0.0]), np.zeros(3), np.array([1.0, 0.0, 0.5])]
    greys = [_grey(_wall_image(texture, c)) for c in centres]
    reference, sources = (
        (greys[1], _pose(centres[1])),
        [(greys[0], _pose(centres[0])), (greys[2], _pose(centres[2]))],
    )
    depth = sweep_depth(CAMERA, reference, sources, CAMERA.height)

    found = np.isfinite(depth)
    assert found.mean() > 0.5
    plane_step = (1 / SWEEP_NEAR_M - 1 / SWEEP_FAR_M) / (SWEEP_PLANES - 1)
    planes_off = np.abs(1 / depth[found] - 1 / WALL_Z) / plane_step
    # A plane step is 0.4-0.5 px of disparity here: the match is good to about a pixel.
    assert np.median(planes_off) <= 1 and np.percentile(planes_off, 95) <= 3

    blank = [(np.full_like(g, 0.6), T) for g, (_, T) in zip(greys, [reference, *sources], strict=True)]
    assert not np.isfinite(sweep_depth(CAMERA, blank[0], blank[1:], CAMERA.height)).any()


def test_depths_a_window_may_have_taken_from_a_nearer_surface_beside_them_are_left_out() -> None:
    # A blank sky over rows 0-9 of the image and a textured roof 20 m away under it; the roof's
    # depth has spread 3 rows up into the sky (rows 7-9), where the windows reach the roof. A
    # building 40 m away beside the roof from column 50 on; a gentle slope (0.5 % a pixel).
    grey = _texture()[:30, :80].copy()
    grey[:10] = 0.6
    depth = np.full((30, 80), 20.0) * 1.005 ** np.arange(80)[None, :]
    depth[:, 50:] = 40.0
    depth[:7] = np.nan
    kept = np.isfinite(without_fattening(depth, grey))
    assert not kept[:10].any() and kept[10:13, :40].all()  # the band over the roof, not the roof
    # within three pixels of the jump (between columns 49 and 50), as a 7-pixel window reaches
    assert not kept[13:, 47:53].any() and not kept[20, 46] and not kept[20, 53]
    assert kept[20, 45] and kept[20, 54] and kept[20:, :40].all() and kept[20:, 57:].all()
    assert np.array_equal(without_fattening(depth, grey)[kept], depth[kept])
    # A textured patch without a depth (too little correlation) is no sky: the rows under it stay.
    depth[15:18, 20:30] = np.nan
    assert np.isfinite(without_fattening(depth, grey)[18:21, 20:30]).all()


def test_cells_lie_on_the_wall_and_none_where_the_lidar_explains_it_or_a_pixel_moves() -> None:
    texture = _texture(1)
    centres = [np.array([x, 0.0, 0.0]) for x in (-3.0, -1.5, 0.0, 1.5, 3.0)]
    images = [_wall_image(texture, c) for c in centres]
    poses = np.stack([_pose(c) for c in centres])
    no_returns = [np.zeros((CAMERA.height, CAMERA.width), np.float32)] * len(centres)  # all above the LiDAR

    sweeps = keyframe_sweeps(CAMERA, images, poses, no_returns, [None] * len(centres))
    cells = swept_cells(CAMERA, images, poses, no_returns, sweeps, np.zeros((0, 3)))
    assert cells.n_references == len(centres)
    assert len(cells.triangles) > 100
    assert np.allclose(cells.triangles[..., 2], WALL_Z, rtol=0.05)
    first_halves = cells.triangles[: len(cells.triangles) // 2]  # corners 0, 1, 2 of each square
    side = np.linalg.norm(first_halves[:, 1] - first_halves[:, 0], axis=1)
    assert np.allclose(np.median(side), CELL_PX * WALL_Z / CAMERA.fx, rtol=0.1)

    # LiDAR returns on the wall explain every cell; a mask of moving pixels in every view leaves none.
    wall = np.stack(np.meshgrid(np.linspace(-8, 8, 161), np.linspace(-5, 5, 101), [WALL_Z]), -1).reshape(
        -1, 3
    )
    assert len(swept_cells(CAMERA, images, poses, no_returns, sweeps, wall).triangles) == 0
    everything = np.ones((CAMERA.height, CAMERA.width), bool)
    masked = keyframe_sweeps(CAMERA, images, poses, no_returns, [everything] * len(centres))
    assert masked == [None] * len(centres)
    assert len(swept_cells(CAMERA, images, poses, no_returns, masked, np.zeros((0, 3))).triangles) == 0


def test_cells_near_a_plane_the_lidar_measured_move_onto_it() -> None:
    texture = _texture(2)
    centres = [np.array([x, 0.0, 0.0]) for x in (-3.0, -1.5, 0.0, 1.5, 3.0)]
    images = [_wall_image(texture, c) for c in centres]
    poses = np.stack([_pose(c) for c in centres])
    no_returns = [np.zeros((CAMERA.height, CAMERA.width), np.float32)] * len(centres)
    sweeps = keyframe_sweeps(CAMERA, images, poses, no_returns, [None] * len(centres))

    # The LiDAR's plane of the wall, 2 % behind where stereo puts it, measured every 2 m across it.
    measured = WALL_Z * 1.02
    xs = np.arange(-10.0, 10.5, 2.0)
    planes = UprightPlanes(
        np.column_stack([xs, np.zeros_like(xs), np.full_like(xs, measured)]),
        np.tile([1.0, 0.0, 0.0], (len(xs), 1)),
        np.array([0.0, -1.0, 0.0]),  # up is -y in these cameras
    )
    cells = swept_cells(CAMERA, images, poses, no_returns, sweeps, np.zeros((0, 3)), planes)
    assert len(cells.triangles) > 100 and cells.n_snapped == len(cells.triangles) // 2
    np.testing.assert_allclose(cells.triangles[..., 2], measured, rtol=1e-9)
