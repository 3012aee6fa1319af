"""A trained, view-dependent background ("sky"): what a camera sees where the triangles leave
accumulated opacity below one.

Its colour is a function of a world-space direction ``d``:
``sigmoid(Σ_k c_k Y_k(d) + m(d))`` per RGB channel, with ``Y_k`` the real spherical harmonics up to
degree ``L`` (``(L + 1)²`` coefficients ``c``, the 3DGS basis and order) and ``m`` an optional map:
the sum of :data:`MAP_LEVELS` equirectangular grids over the directions (azimuth about world z,
elevation from its horizon), sampled bilinearly. The harmonics are too smooth for a street's sky
between roofs and for structure beyond the LiDAR's reach; the map holds them (its finest texels
are 0.7° wide), and its coarse levels fill what the fine ones rarely see. One tensor holds both,
``(K, 3)``: the harmonics' coefficients, then the map's texels level by level (row-major).

Where it lies: at infinity (``d`` is the viewing direction), or on a sphere about the cameras, where
``d`` points from the sphere's centre to where the pixel's ray leaves it. Beyond the LiDAR's reach a
street's background is mostly structure 80-200 m away, not sky; seen from a car that drives 20 m
it moves against the sky, which a background at infinity cannot show (:func:`background_sphere`).
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np
import torch
import torch.nn.functional as F
from torch import Tensor

from rig.camera import CameraModel
from rig.mesh_rays import pixel_rays

MAX_DEGREE = 3
#: The map's grids (rows, columns), coarse to fine: 11.25°, 2.8° and 0.7° texels.
MAP_LEVELS = ((16, 32), (64, 128), (256, 512))
MAP_TEXELS = sum(rows * columns for rows, columns in MAP_LEVELS)
#: Fewer directions than this read only the texels around them (:func:`map_values`): a room's
#: training view shows the background at a few pixels, and building, padding and sampling the
#: 256×512 grid for them cost more than the rest of the background; many directions (a street's
#: sky) sample the whole grids, whose gradient is one scatter per grid instead of twelve rows per
#: direction.
GATHER_BELOW = 8192
_C0 = 0.28209479177387814
_C1 = 0.4886025119029199
_C2 = (1.0925484305920792, -1.0925484305920792, 0.31539156525252005, -1.0925484305920792, 0.5462742152960396)
_C3 = (
    -0.5900435899266435, 2.890611442640554, -0.4570457994644658, 0.3731763325901154, -0.4570457994644658,
    1.445305721320277, -0.5900435899266435,
)  # fmt: skip
#: Colours the initial constant is clamped to, so that the sigmoid starts with a usable gradient.
_INIT_RANGE = (0.02, 0.98)
#: The background's sphere lies this many times the LiDAR's reach beyond the farthest camera from its
#: centre. On the 8 s virtual street (LiDAR reach 62 m, cameras within 10 m of their mean) spheres of
#: 80, 150 and 300 m gave 28.11, 28.14 and 27.98 dB on the static test pixels, 27.89 at infinity.
REACH_MULTIPLE = 2.0
#: The LiDAR's reach: this percentile of the views' LiDAR depths (a few returns reach further).
REACH_PERCENTILE = 99.0
#: How many cameras' ray grids are kept (a run has one; the viewer one more).
_RAYS_KEPT = 4
_rays: dict[tuple, tuple[Tensor, Tensor]] = {}


def n_coefficients(degree: int, with_map: bool = False) -> int:
    """Rows per channel of a background of harmonics of ``degree`` (``(degree + 1)²``), and of
    the map's :data:`MAP_TEXELS` when ``with_map``."""
    return (degree + 1) ** 2 + (MAP_TEXELS if with_map else 0)


def layout_of(n: int) -> tuple[int, bool]:
    """The degree of a background of ``n`` rows per channel and whether a map follows its
    harmonics (ValueError if no layout has ``n`` rows)."""
    layouts = {n_coefficients(d, m): (d, m) for d in range(MAX_DEGREE + 1) for m in (False, True)}
    if n not in layouts:
        raise ValueError(f"expected {', '.join(map(str, sorted(layouts)))} coefficients per channel, got {n}")
    return layouts[n]


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


def map_values(texels: Tensor, directions: Tensor) -> Tensor:
    """The map of ``texels`` ``(MAP_TEXELS, 3)`` along unit world ``directions`` ``(N, 3)``: the sum
    of its levels sampled bilinearly ``(N, 3)`` at texel centres (``F.grid_sample``'s
    ``align_corners=False``, the rows clamped at the poles), continuous across azimuth ±180°."""
    x, y, z = directions.unbind(-1)
    azimuth = torch.atan2(y, x) / math.pi  # [-1, 1] across each grid's columns
    elevation = -torch.asin(z.clamp(-1.0, 1.0)) / (math.pi / 2)  # -1: up, the grid's first row
    if len(directions) < GATHER_BELOW:
        return _gathered_map_values(texels, azimuth, elevation)
    values = torch.zeros_like(directions)
    # One split, not a slice per level: each slice's backward pass writes a zero gradient of all texels.
    levels = texels.split([rows * columns for rows, columns in MAP_LEVELS])
    for (rows, columns), level in zip(MAP_LEVELS, levels, strict=True):
        grid = level.T.reshape(1, 3, rows, columns)
        # One column more on each side, copied from the other edge: the map closes at azimuth ±180°.
        wrapped = F.pad(grid, (1, 1, 0, 0), mode="circular")
        at = torch.stack([azimuth * columns / (columns + 2), elevation], dim=-1).to(grid)
        sampled = F.grid_sample(wrapped, at[None, None], padding_mode="border", align_corners=False)
        values = values + sampled[0, :, 0].T
    return values


def _gathered_map_values(texels: Tensor, azimuth: Tensor, elevation: Tensor) -> Tensor:
    """:func:`map_values` at ``azimuth`` and ``elevation`` ``(N,)`` (in [-1, 1], as there) from the
    four texels of each level around each direction only, read in one gather."""
    indices, weights, start = [], [], 0
    for rows, columns in MAP_LEVELS:
        u = (azimuth + 1) * (columns / 2) - 0.5  # texel-centre coordinates: column c at u = c
        v = (((elevation + 1) * rows - 1) / 2).clamp(0, rows - 1)
        u0, v0 = u.floor(), v.floor()
        fu, fv = u - u0, v - v0
        left, right = u0.long() % columns, (u0.long() + 1) % columns  # the map closes at ±180°
        top = start + v0.long() * columns
        bottom = start + (v0.long() + 1).clamp(max=rows - 1) * columns
        indices += [top + left, top + right, bottom + left, bottom + right]
        weights += [(1 - fu) * (1 - fv), fu * (1 - fv), (1 - fu) * fv, fu * fv]
        start += rows * columns
    # index_select's gradient is index_add_, which sums repeated texels in a fixed order (plain
    # indexing's accumulating scatter did not, and a resumed run lost its bit-for-bit result).
    index = torch.stack(indices, dim=1)  # (N, 4 * levels)
    corners = texels.index_select(0, index.reshape(-1)).view(*index.shape, 3)
    return (corners * torch.stack(weights, dim=1)[..., None]).sum(dim=1)


def background_rgb(coefficients: Tensor, directions: Tensor) -> Tensor:
    """RGB in (0, 1) ``(N, 3)`` of the background ``coefficients`` ``(K, 3)`` (harmonics, then the
    map's texels if any) seen along unit world ``directions`` ``(N, 3)``."""
    degree, with_map = layout_of(len(coefficients))
    harmonics, texels = coefficients.split([n_coefficients(degree), MAP_TEXELS if with_map else 0])
    logits = sh_basis(directions, degree) @ harmonics
    if with_map:
        logits = logits + map_values(texels, directions)
    return torch.sigmoid(logits)


def constant_background(
    rgb: Sequence[float] | Tensor,
    degree: int,
    *,
    with_map: bool = False,
    dtype: torch.dtype = torch.float32,
    device: torch.device | str = "cpu",
) -> Tensor:
    """Coefficients ``(K, 3)`` (a leaf that requires grad) of a background of one colour ``rgb``
    ``(3,)`` in [0, 1] in every direction, with a map when ``with_map``: only the constant term is
    set."""
    rgb = torch.as_tensor(rgb, dtype=torch.float64).clamp(*_INIT_RANGE)
    coefficients = torch.zeros(n_coefficients(degree, with_map), 3, dtype=torch.float64)
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


def background_sphere(camera_centres: np.ndarray, lidar_depths: np.ndarray) -> np.ndarray | None:
    """The sphere ``(4,)`` (centre, radius; m) the background lies on for cameras at
    ``camera_centres`` ``(N, 3)`` whose LiDAR depths are ``lidar_depths`` ``(M,)`` (> 0): about their
    mean, :data:`REACH_MULTIPLE` times the LiDAR's reach (:data:`REACH_PERCENTILE`) beyond the
    farthest of them. None (at infinity) without cameras or depths."""
    if len(camera_centres) == 0 or len(lidar_depths) == 0:
        return None
    centre = camera_centres.mean(axis=0)
    spread = float(np.linalg.norm(camera_centres - centre, axis=1).max())
    reach = float(np.percentile(lidar_depths, REACH_PERCENTILE))
    return np.append(centre, spread + REACH_MULTIPLE * reach)


def sphere_directions(directions: Tensor, origin: Tensor, sphere: Tensor | None) -> Tensor:
    """Unit directions ``(N, 3)`` from the centre of ``sphere`` ``(4,)`` (centre, radius) to where rays
    from ``origin`` ``(3,)`` (inside it) along unit ``directions`` ``(N, 3)`` leave it; ``directions``
    themselves when ``sphere`` is None (at infinity)."""
    if sphere is None:
        return directions
    offset = origin - sphere[:3]
    along = directions @ offset
    # |offset + t d|² = r², the positive root (the origin lies inside, so the other is negative).
    t = -along + torch.sqrt((along**2 - offset @ offset + sphere[3] ** 2).clamp(min=0.0))
    return F.normalize(offset + t[:, None] * directions, dim=1)


def background_image(
    coefficients: Tensor, camera: CameraModel, T_cam_world: Tensor, sphere: Tensor | None = None
) -> Tensor:
    """The background ``(H, W, 3)`` on ``sphere`` ``(4,)`` (None: at infinity) seen by ``camera`` at
    ``T_cam_world`` ``(4, 4)`` (zero at pixels the camera model cannot back-project); differentiable
    in ``coefficients`` ``(K, 3)``."""
    width, height = camera.size
    return background_pixels(coefficients, camera, T_cam_world, sphere=sphere).view(height, width, 3)


def background_pixels(
    coefficients: Tensor,
    camera: CameraModel,
    T_cam_world: Tensor,
    pixels: Tensor | None = None,
    sphere: Tensor | None = None,
) -> Tensor:
    """The background at the row-major pixel indices ``pixels`` ``(N,)`` (all ``H·W`` pixels when
    None) as ``(N, 3)``; as :func:`background_image` otherwise."""
    rays, valid = camera_rays(camera, coefficients.device, coefficients.dtype)
    if pixels is not None:
        rays, valid = rays[pixels], valid[pixels]
    R_cam_world, t_cam_world = T_cam_world[:3, :3].to(coefficients), T_cam_world[:3, 3].to(coefficients)
    # Row vectors: d_world = R_world_cam d_cam = R_cam_world^T d_cam, i.e. d_cam^T R_cam_world.
    directions = rays @ R_cam_world
    if sphere is not None:
        directions = sphere_directions(directions, -R_cam_world.T @ t_cam_world, sphere.to(coefficients))
    return background_rgb(coefficients, directions) * valid[:, None]
