"""Training views at half resolution, for the first iterations of a run.

Early in training the triangles are soft (the window's σ is large) and far from their place, so a
render at half the image size carries the same gradient direction for a quarter of the pixels: the
rasteriser and the image losses cost about a quarter as much. Many splatting trainers start
coarse for this reason. The half-size view is the full one pooled over 2 × 2 blocks:

- the image is averaged (what a camera with pixels twice as large would record);
- the LiDAR depth keeps the nearest return of a block (never a mix across a depth edge), and the
  normal prior the normal of that same pixel;
- the background and moving-object masks hold where any pixel of the block held.
"""

from __future__ import annotations

import math

import torch
import torch.nn.functional as F
from torch import Tensor

from rig.camera import CameraModel
from splat.config import TrainConfig
from splat.views import View


def coarse_iterations(camera: CameraModel, config: TrainConfig) -> int:
    """How many iterations of a run with ``config`` start at half resolution: ``coarse_until`` of
    them, or none when the half-size images of ``camera`` would have fewer than
    ``coarse_min_side_px`` pixels on their shorter side."""
    if min(camera.width, camera.height) // 2 < config.coarse_min_side_px:
        return 0
    return math.ceil(config.coarse_until * config.iterations)


def half_camera(camera: CameraModel) -> CameraModel:
    """``camera`` for images pooled over 2 × 2 blocks (an odd last row or column is dropped)."""
    even = CameraModel(camera.model, 2 * (camera.width // 2), 2 * (camera.height // 2), camera.K, camera.dist)
    return even.scaled(camera.width // 2, camera.height // 2)


def _blocks(image: Tensor) -> Tensor:
    """``(H, W, C)`` → ``(1, C, H, W)`` cropped to even sizes, for 2 × 2 pooling."""
    height, width = 2 * (image.shape[0] // 2), 2 * (image.shape[1] // 2)
    return image[:height, :width].permute(2, 0, 1)[None]


def _pooled_mask(mask: Tensor | None) -> Tensor | None:
    if mask is None:
        return None
    return F.max_pool2d(_blocks(mask[..., None].float()), 2)[0, 0] > 0


def half_view(view: View) -> View:
    """``view`` pooled over 2 × 2 blocks (module docstring); ``(H // 2, W // 2)`` images."""
    image = F.avg_pool2d(_blocks(view.image), 2)[0].permute(1, 2, 0).contiguous()
    depth = normal = None
    if view.depth is not None:
        # Nearest return of each block: the largest negated depth, with empty pixels at -inf.
        negated = torch.where(view.depth > 0, -view.depth, -torch.inf)
        pooled, index = F.max_pool2d(_blocks(negated[..., None]), 2, return_indices=True)
        depth = torch.where(torch.isfinite(pooled[0, 0]), -pooled[0, 0], 0.0)
        if view.normal is not None:
            flat = _blocks(view.normal).flatten(2)  # (1, 3, H·W) of the even crop
            normal = flat.gather(2, index.flatten(2).expand(1, 3, -1))[0].T.reshape(*depth.shape, 3)
            normal = torch.where((depth > 0)[..., None], normal, 0.0)
    elif view.normal is not None:
        pooled_normal = F.avg_pool2d(_blocks(view.normal), 2)[0].permute(1, 2, 0)
        normal = pooled_normal / pooled_normal.norm(dim=-1, keepdim=True).clamp(min=1e-8)
    return View(
        view.name,
        view.T_cam_world,
        image,
        depth,
        normal,
        background_mask=_pooled_mask(view.background_mask),
        moving_mask=_pooled_mask(view.moving_mask),
    )
