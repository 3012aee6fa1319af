"""Synthetic triangle scenes for tests and benchmarks."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import torch
from torch import Tensor

from rig.camera import CameraModel


@dataclass
class TriangleScene:
    """Independent triangles (each owns its three vertices) seen by ``camera`` at identity pose.

    vertices ``(3F, 3)``, faces ``(F, 3)``, colors ``(3F, 3)``, opacities ``(3F,)``, sigma ``(F,)``.
    """

    vertices: Tensor
    faces: Tensor
    colors: Tensor
    opacities: Tensor
    sigma: Tensor
    camera: CameraModel

    def tensors(self) -> tuple[Tensor, Tensor, Tensor, Tensor, Tensor]:
        return self.vertices, self.faces, self.colors, self.opacities, self.sigma


def pinhole(width: int, height: int, fov_deg: float = 70.0) -> CameraModel:
    """A distortion-free pinhole camera with the given horizontal field of view."""
    f = 0.5 * width / math.tan(math.radians(fov_deg) / 2)
    K = np.array([[f, 0, (width - 1) / 2], [0, f, (height - 1) / 2], [0, 0, 1]])
    return CameraModel("pinhole", width, height, K, np.zeros(0))


def random_scene(
    n: int,
    camera: CameraModel,
    *,
    size_px: tuple[float, float] = (2.0, 20.0),
    opacity: tuple[float, float] = (0.3, 1.0),
    sigma: tuple[float, float] = (0.5, 2.0),
    seed: int = 0,
    dtype: torch.dtype = torch.float32,
) -> TriangleScene:
    """``n`` random triangles of ``size_px`` pixels (circumradius x 2) with room-like depth.

    Depth grows towards the top of the image (floor near, far wall at the top, 1-10 m) with
    +-0.3 m jitter; triangles face the camera within 60 degrees.
    """
    g = torch.Generator().manual_seed(seed)
    u = lambda *shape: torch.rand(*shape, generator=g, dtype=torch.float64)  # noqa: E731
    px = u(n) * camera.width
    py = u(n) * camera.height
    z = 1.0 + 9.0 * (1.0 - py / camera.height) ** 2 + 0.6 * (u(n) - 0.5)
    centre = torch.stack([(px - camera.cx) / camera.fx * z, (py - camera.cy) / camera.fy * z, z], -1)
    radius = 0.5 * (size_px[0] + (size_px[1] - size_px[0]) * u(n)) * z / camera.fx
    angle = 2 * math.pi * (torch.arange(3) / 3 + 0.2 * (u(n, 3) - 0.5)) + 2 * math.pi * u(n, 1)
    local = torch.stack([torch.cos(angle), torch.sin(angle), torch.zeros_like(angle)], -1)
    tilt, axis = math.pi / 3 * u(n), 2 * math.pi * u(n)
    k = torch.stack([torch.cos(axis), torch.sin(axis), torch.zeros_like(axis)], -1)  # tilt axis
    # Rodrigues rotation of the in-plane (z = 0) offsets about k by `tilt`.
    cos, sin = torch.cos(tilt)[:, None, None], torch.sin(tilt)[:, None, None]
    kk = k[:, None, :].expand_as(local)
    rotated = (
        local * cos
        + torch.linalg.cross(kk, local) * sin
        + kk * (kk * local).sum(-1, keepdim=True) * (1 - cos)
    )
    vertices = centre[:, None, :] + radius[:, None, None] * rotated
    lo, hi = opacity
    s_lo, s_hi = sigma
    return TriangleScene(
        vertices=vertices.reshape(-1, 3).to(dtype),
        faces=torch.arange(3 * n).reshape(n, 3),
        colors=u(3 * n, 3).to(dtype),
        opacities=(lo + (hi - lo) * u(3 * n)).to(dtype),
        sigma=(s_lo + (s_hi - s_lo) * u(n)).to(dtype),
        camera=camera,
    )
