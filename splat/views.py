"""Training views: a scene's keyframes as tensors, and the keyframes that add no new view."""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property

import numpy as np
import torch
from torch import Tensor

from rig.transforms import distance_and_angle, invert
from slam_bridge.scene import Keyframe, Scene
from splat.camera_blur import blurred
from splat.exposure import through_color_map


@dataclass
class View:
    """One keyframe ready for rendering (``H, W`` image size).

    Attributes:
        name: keyframe name.
        T_cam_world: ``(4, 4)`` world-to-camera transform.
        image: ``(H, W, 3)`` RGB in [0, 1].
        depth: ``(H, W)`` LiDAR depth (0 = no return), or None when the keyframe has none.
        normal: ``(H, W, 3)`` normal prior (0 = none), or None when the keyframe has none.
        background_mask: ``(H, W)`` bool, where training composites the background; None:
            wherever the triangles leave alpha below one.
        moving_mask: ``(H, W)`` bool, pixels of moving objects the photometric loss leaves out,
            or None when the keyframe saw none (:meth:`~slam_bridge.scene.Scene.moving_mask`).
        image_moments: the image's :func:`~splat.losses.image_moments` ``(1, 6, H, W)``, once the
            trainer has kept them (None: D-SSIM computes them each time).
        color_map: ``(3, 3)`` colour matrix a held-out view's render is scored through (its
            exposure, :func:`splat.exposure.held_out_maps`), or None (the render as it is).
        blur_px: width (px) of the camera's blur a held-out view's render is scored through
            (:mod:`splat.camera_blur`); 0: none.
    """

    name: str
    T_cam_world: Tensor
    image: Tensor
    depth: Tensor | None
    normal: Tensor | None
    background_mask: Tensor | None = None
    moving_mask: Tensor | None = None
    image_moments: Tensor | None = None
    color_map: Tensor | None = None
    blur_px: float = 0.0

    @cached_property
    def normal_known(self) -> Tensor | None:
        """``(H, W)`` bool: the pixels whose normal prior is finite and non-zero (None without a
        prior). Kept once made: the densification statistics read it at every iteration."""
        if self.normal is None:
            return None
        return torch.isfinite(self.normal).all(dim=-1) & (self.normal.abs().sum(dim=-1) > 0)

    def scored_rgb(self, rgb: Tensor) -> Tensor:
        """A render ``(H, W, 3)`` of this view as it is scored: through the camera's blur
        (:attr:`blur_px`) and :attr:`color_map`, clipped to [0, 1]."""
        return through_color_map(blurred(rgb, self.blur_px), self.color_map)


def load_views(
    scene: Scene, keyframes: list[Keyframe], dtype: torch.dtype = torch.float32, device: str = "cpu"
) -> list[View]:
    """Load ``keyframes`` of ``scene`` as :class:`View` tensors on ``device``."""
    views = []
    for k in keyframes:
        depth = scene.depth(k)
        normal = scene.normals(k)
        moving = scene.moving_mask(k)
        views.append(
            View(
                k.name,
                torch.as_tensor(invert(k.T_world_cam), dtype=dtype, device=device),
                torch.as_tensor(scene.image(k) / 255.0, dtype=dtype, device=device),
                torch.as_tensor(depth, dtype=dtype, device=device) if (depth > 0).any() else None,
                torch.as_tensor(normal, dtype=dtype, device=device) if np.abs(normal).sum() > 0 else None,
                moving_mask=None if moving is None else torch.as_tensor(moving, device=device),
            )
        )
    return views


def redundant_keyframes(keyframes: list[Keyframe], motion_m: float, turn_deg: float) -> list[int]:
    """Indices of keyframes that add no new view: within ``motion_m`` and ``turn_deg`` of an
    earlier kept keyframe (a robot standing still, typically at the start and the end)."""
    kept: list[np.ndarray] = []
    redundant = []
    for i, k in enumerate(keyframes):
        T = k.T_world_cam
        for K in kept:
            moved, angle = distance_and_angle(T, K)
            if moved <= motion_m and angle <= np.radians(turn_deg):
                redundant.append(i)
                break
        else:
            kept.append(T)
    return redundant
