"""Half-resolution training views: what each pooled image keeps."""

from __future__ import annotations

import numpy as np
import torch

from rig.camera import CameraModel
from splat.coarse_views import coarse_iterations, half_camera, half_view
from splat.config import make_config
from splat.views import View


def test_half_camera_sees_the_same_rays_through_the_pooled_pixels():
    camera = CameraModel("pinhole", 7, 5, np.array([[10.0, 0, 3.2], [0, 11.0, 2.1], [0, 0, 1]]), np.zeros(0))
    half = half_camera(camera)
    assert half.size == (3, 2)
    # Half-pixel (1, 0) covers full pixels x 2..3, y 0..1: its centre is the full image's (2.5, 0.5).
    point = camera.unproject(np.array([[2.5, 0.5]]))
    np.testing.assert_allclose(half.project(point), [[1.0, 0.0]], atol=1e-12)


def test_half_view_averages_colour_keeps_the_nearest_return_and_its_normal():
    image = torch.arange(4 * 4 * 3, dtype=torch.float32).reshape(4, 4, 3) / 48
    depth = torch.zeros(4, 4)
    depth[0, 0], depth[1, 1] = 5.0, 2.0  # one block, two returns: the nearer one is kept
    depth[3, 3] = 7.0
    normal = torch.zeros(4, 4, 3)
    normal[0, 0] = torch.tensor([1.0, 0, 0])
    normal[1, 1] = torch.tensor([0, 1.0, 0])
    normal[3, 3] = torch.tensor([0, 0, 1.0])
    moving = torch.zeros(4, 4, dtype=torch.bool)
    moving[2, 1] = True
    view = View("k", torch.eye(4), image, depth, normal, background_mask=None, moving_mask=moving)

    half = half_view(view)

    torch.testing.assert_close(half.image[0, 1], image[0:2, 2:4].reshape(-1, 3).mean(dim=0))
    torch.testing.assert_close(half.depth, torch.tensor([[2.0, 0.0], [0.0, 7.0]]))
    torch.testing.assert_close(half.normal[0, 0], torch.tensor([0, 1.0, 0]))
    torch.testing.assert_close(half.normal[1, 1], torch.tensor([0, 0, 1.0]))
    assert float(half.normal[0, 1].abs().sum()) == 0.0
    assert half.moving_mask.tolist() == [[False, False], [True, False]]
    assert half.background_mask is None


def test_the_coarse_start_covers_its_fraction_unless_the_half_images_are_too_small():
    config = make_config("ours", "default", iterations=1001, coarse_until=0.25)
    K = np.array([[250.0, 0, 159.5], [0, 250.0, 119.5], [0, 0, 1]])
    room = CameraModel("pinhole", 320, 240, K, np.zeros(0))
    assert coarse_iterations(room, config) == 251  # iterations 0..250
    assert coarse_iterations(room.scaled(160, 120), config) == 0  # 80x60 would lose detail
    assert coarse_iterations(room, config.model_copy(update={"coarse_until": 0.0})) == 0
