"""A trained, view-dependent background ("sky"): what a camera sees where the triangles leave
accumulated opacity below one.

Its colour is a function of the world-space viewing direction ``d`` only (it lies at infinity):
``sigmoid(Σ_k c_k Y_k(d))`` per RGB channel, with ``Y_k`` the real spherical harmonics up to
degree ``L`` (``K = (L + 1)²`` coefficients ``c`` ``(K, 3)``, the 3DGS basis and order).
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import torch
from torch import Tensor

from rig.camera import CameraModel
from rig.mesh_rays import pixel_rays

MAX_DEGREE = 3
_C0 = 0.28209479177387814
_C1 = 0.4886025119029199
_C2 = (1.0925484305920792, -1.0925484305920792, 0.31539156525252005, -1.0925484305920792, 0.5462742152960396)
_C3 = (
    -0.5900435899266435, 2.890611442640554, -0.4570457994644658, 0.3731763325901154, -0.4570457994644658,
    1.445305721320277, -0.5900435899266435,
)  # fmt: skip
#: Colours the initial constant is clamped to, so that the sigmoid starts with a usable gradient.
_INIT_RANGE = (0.02, 0.98)
#: How many cameras' ray grids are kept (a run has one; the viewer one more).
_RAYS_KEPT = 4
_rays: dict[tuple, tuple[Tensor, Tensor]] = {}


def n_coefficients(degree: int) -> int:
    """``(degree + 1)²``: the coefficients per channel of a degree-``degree`` background."""
    return (degree + 1) ** 2


def degree_of(n: int) -> int:
    """The degree whose background has ``n`` coefficients per channel (ValueError if none does)."""
    degree = round(n**0.5) - 1
    if n < 1 or n_coefficients(degree) != n or degree > MAX_DEGREE:
        allowed = ", ".join(str(n_coefficients(d)) for d in range(MAX_DEGREE + 1))
        raise ValueError(f"expected {allowed} coefficients per channel, got {n}")
    return degree


def sh_basis(directions: Tensor, degree: int) -> Tensor:
    """Real spherical harmonics ``(N, (degree + 1)²)`` of unit ``directions`` ``(N, 3)``."""
    if not 0 <= degree <= MAX_DEGREE:
        raise ValueError(f"expected a degree in [0, {MAX_DEGREE}], got {degree}")
    x, y, z = directions.unbind(-1)
    basis = [torch.full_like(x, _C0)]
    if degree >= 1:
        basis += [-_C1 * y, _C1 * z, -_C1 * x]
    if degree >= 2:
        xx, yy, zz = x * x, y * y, z * z
        basis += [
            _C2[0] * x * y, _C2[1] * y * z, _C2[2] * (2 * zz - xx - yy), _C2[3] * x * z, _C2[4] * (xx - yy),
        ]  # fmt: skip
    if degree >= 3:
        basis += [
            _C3[0] * y * (3 * xx - yy), _C3[1] * x * y * z, _C3[2] * y * (4 * zz - xx - yy),
            _C3[3] * z * (2 * zz - 3 * xx - 3 * yy), _C3[4] * x * (4 * zz - xx - yy), _C3[5] * z * (xx - yy),
            _C3[6] * x * (xx - 3 * yy),
        ]  # fmt: skip
    return torch.stack(basis, dim=-1)


def background_rgb(coefficients: Tensor, directions: Tensor) -> Tensor:
    """RGB in (0, 1) ``(N, 3)`` of the background ``coefficients`` ``(K, 3)`` seen along unit world
    ``directions`` ``(N, 3)``."""
    basis = sh_basis(directions, degree_of(len(coefficients)))
    return torch.sigmoid(basis @ coefficients)


def constant_background(
    rgb: Sequence[float] | Tensor,
    degree: int,
    *,
    dtype: torch.dtype = torch.float32,
    device: torch.device | str = "cpu",
) -> Tensor:
    """Coefficients ``(K, 3)`` (a leaf that requires grad) of a background of one colour ``rgb``
    ``(3,)`` in [0, 1] in every direction: only the constant term is set."""
    rgb = torch.as_tensor(rgb, dtype=torch.float64).clamp(*_INIT_RANGE)
    coefficients = torch.zeros(n_coefficients(degree), 3, dtype=torch.float64)
    coefficients[0] = torch.logit(rgb) / _C0
    return coefficients.to(device=device, dtype=dtype).requires_grad_(True)


def camera_rays(camera: CameraModel, device: torch.device, dtype: torch.dtype) -> tuple[Tensor, Tensor]:
    """Unit camera-frame rays ``(H·W, 3)`` of every pixel (row-major; zero where the camera model
    cannot back-project the pixel) and where they exist ``(H·W,)`` bool. Cached per camera."""
    key = (camera.model, camera.size, camera.K.tobytes(), camera.dist.tobytes(), torch.device(device), dtype)
    if key not in _rays:
        rays = pixel_rays(camera)
        valid = np.isfinite(rays).all(axis=1)
        rays = np.where(valid[:, None], rays, 0.0)
        if len(_rays) >= _RAYS_KEPT:
            _rays.pop(next(iter(_rays)))
        _rays[key] = (
            torch.as_tensor(rays, dtype=dtype, device=device),
            torch.as_tensor(valid, device=device),
        )
    return _rays[key]


def background_image(coefficients: Tensor, camera: CameraModel, T_cam_world: Tensor) -> Tensor:
    """The background ``(H, W, 3)`` seen by ``camera`` at ``T_cam_world`` ``(4, 4)`` (zero at pixels
    the camera model cannot back-project); differentiable in ``coefficients`` ``(K, 3)``."""
    width, height = camera.size
    return background_pixels(coefficients, camera, T_cam_world).view(height, width, 3)


def background_pixels(
    coefficients: Tensor, camera: CameraModel, T_cam_world: Tensor, pixels: Tensor | None = None
) -> Tensor:
    """The background at the row-major pixel indices ``pixels`` ``(N,)`` (all ``H·W`` pixels when
    None) as ``(N, 3)``; as :func:`background_image` otherwise."""
    rays, valid = camera_rays(camera, coefficients.device, coefficients.dtype)
    if pixels is not None:
        rays, valid = rays[pixels], valid[pixels]
    # Row vectors: d_world = R_world_cam d_cam = R_cam_world^T d_cam, i.e. d_cam^T R_cam_world.
    directions = rays @ T_cam_world[:3, :3].to(coefficients)
    return background_rgb(coefficients, directions) * valid[:, None]
