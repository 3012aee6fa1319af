"""Per-triangle set-up: projection, culling, depth order, and the window function's coefficients
(the numbers the rasterisers read, see ``csrc/triangle_math.h``).

This PyTorch version (differentiable with autograd) is the specification and the reference
backend's set-up; the compiled backends run the same maths in ``csrc/triangle_setup.h`` with a
hand-written backward (:mod:`splat.raster.setup_kernel`), and the tests hold the two together.
"""

from __future__ import annotations

from dataclasses import dataclass

import torch
from torch import Tensor

#: Layout of one row of :attr:`ProjectedTriangles.params` (mirrors ``csrc/triangle_math.h``).
LINE, COLOR, INV_DEPTH, OPACITY, SIGMA, NORMAL, SUPPORT = 0, 9, 18, 21, 22, 23, 26
N_PARAMS = 27
ALPHA_MIN = 1.0 / 255.0
#: A triangle whose plane is this close to containing the viewing ray (|cos|) is edge-on.
EDGE_ON_COS = 1e-3
#: Triangles whose projected inradius is below this (pixels) are too thin to render stably.
MIN_INRADIUS_PX = 1e-2
#: Pixel-box padding that makes binning conservative against rounding in the support estimate.
BOX_PAD_PX = 0.5


@dataclass(frozen=True)
class Intrinsics:
    """Distortion-free pinhole intrinsics (pixel centres at integers, OpenCV convention)."""

    fx: float
    fy: float
    cx: float
    cy: float
    width: int
    height: int


@dataclass
class ProjectedTriangles:
    """Visible triangles in front-to-back order, ready to rasterise.

    Attributes:
        params: ``(K, 27)`` kernel parameters (see ``csrc/triangle_math.h``), differentiable.
        bounds: ``(K, 4)`` int32 inclusive pixel box ``x0, y0, x1, y1`` clipped to the image.
        index: ``(K,)`` int64 index of each row in the caller's face list.
    """

    params: Tensor
    bounds: Tensor
    index: Tensor


def _length(x: Tensor, keepdim: bool = False) -> Tensor:
    """Euclidean length of rows ``(K, 3)``, scaled by their largest |component| first: the squares
    of a float32 cross product of ~1e-10 m edges underflow to 0 (then the unit normal was inf/NaN).
    The scale is held constant for autograd, which is exact because the length is homogeneous.
    (Mirrors ``safe_length`` in ``csrc/triangle_setup.h``.)"""
    m = x.detach().abs().amax(dim=1, keepdim=True)
    m = torch.where(m > 0, m, torch.ones_like(m))
    length = m * (x / m).norm(dim=1, keepdim=True)
    return length if keepdim else length[:, 0]


def _visible(tri_cam: Tensor, opacity: Tensor, sigma: Tensor, intr: Intrinsics, near: float) -> Tensor:
    """``(F,)`` bool: in front of the near plane, not edge-on, not tiny, possibly visible."""
    z = tri_cam[..., 2]
    in_front = (z > near).all(dim=1)
    z_safe = torch.where(in_front[:, None], z, torch.ones_like(z))
    u = intr.fx * tri_cam[..., 0] / z_safe + intr.cx
    v = intr.fy * tri_cam[..., 1] / z_safe + intr.cy
    du, dv = u.roll(-1, dims=1) - u, v.roll(-1, dims=1) - v
    twice_area = (du[:, 0] * (-dv[:, 2]) - dv[:, 0] * (-du[:, 2])).abs()
    inradius = twice_area / torch.hypot(du, dv).sum(dim=1)
    normal = torch.linalg.cross(tri_cam[:, 1] - tri_cam[:, 0], tri_cam[:, 2] - tri_cam[:, 0])
    centroid = tri_cam.mean(dim=1)
    facing = (normal * centroid).sum(dim=1).abs()
    not_edge_on = facing >= EDGE_ON_COS * _length(normal) * _length(centroid)
    on_screen = (
        (u.max(dim=1).values >= -BOX_PAD_PX)
        & (u.min(dim=1).values <= intr.width - 1 + BOX_PAD_PX)
        & (v.max(dim=1).values >= -BOX_PAD_PX)
        & (v.min(dim=1).values <= intr.height - 1 + BOX_PAD_PX)
    )
    # Projections that overflow (float32 with a vertex grazing the near plane, extreme focal
    # lengths) make inf - inf = NaN further on; such a triangle cannot be drawn meaningfully.
    finite = torch.isfinite(u).all(dim=1) & torch.isfinite(v).all(dim=1) & torch.isfinite(twice_area)
    return (
        in_front
        & finite
        & not_edge_on
        & (inradius >= MIN_INRADIUS_PX)  # NaN for collinear points compares False: culled
        & on_screen
        & (opacity >= ALPHA_MIN)
        & (sigma > 0)
    )


def _support_box(q: Tensor, side: Tensor, opacity: Tensor, sigma: Tensor, intr: Intrinsics):
    """Support threshold ``(K,)`` and int32 pixel boxes ``(K, 4)`` of the region alpha >= 1/255.

    That region is ``min_j l_j >= t`` with ``t = (1 / (255 o))^(1/sigma)``: the triangle shrunk
    about its incentre by ``1 - t`` (the window's level sets are homothetic triangles).
    """
    t = (ALPHA_MIN / opacity).pow(1.0 / sigma).clamp(0.0, 1.0)
    # Incentre: vertices weighted by the length of the opposite side (side j joins j and j+1).
    weights = side.roll(-1, dims=1) / side.sum(dim=1, keepdim=True)
    incentre = (weights[..., None] * q).sum(dim=1, keepdim=True)
    shrunk = incentre + (1.0 - t)[:, None, None] * (q - incentre)
    lo = torch.ceil(shrunk.min(dim=1).values - BOX_PAD_PX)
    hi = torch.floor(shrunk.max(dim=1).values + BOX_PAD_PX)
    limit = torch.tensor([intr.width - 1, intr.height - 1], dtype=q.dtype, device=q.device)
    # Clamp on both sides *before* the int32 cast: the support of a visible triangle can lie
    # billions of pixels off the image (a vertex grazing the near plane, extreme intrinsics), and
    # casting such a float to int32 is undefined (x86 gives INT_MIN, a box spanning 2^31 pixels
    # that the binning then walks out of bounds). lo > limit or hi < 0 is an empty box.
    lo = torch.minimum(torch.maximum(lo, torch.zeros_like(lo)), limit + 1)
    hi = torch.maximum(torch.minimum(hi, limit), torch.full_like(hi, -1.0))
    return t, torch.cat([lo, hi], dim=1).to(torch.int32)


def project_triangles(
    vertices: Tensor,
    faces: Tensor,
    colors: Tensor,
    opacities: Tensor,
    sigma: Tensor,
    T_cam_world: Tensor,
    intr: Intrinsics,
    near: float,
) -> ProjectedTriangles:
    """Project and set up triangles for rasterisation.

    Args:
        vertices: ``(V, 3)`` world points. faces: ``(F, 3)`` int64 vertex indices.
        colors: ``(V, 3)`` vertex colours. opacities: ``(V,)`` vertex opacities in [0, 1].
        sigma: ``(F,)`` window sharpness (> 0). T_cam_world: ``(4, 4)`` world-to-camera transform.
        intr: pinhole intrinsics. near: near-plane depth in metres.

    Returns:
        The visible triangles sorted by centroid depth (stable: ties keep face order).
    """
    R, t = T_cam_world[:3, :3], T_cam_world[:3, 3]
    tri_opacity = opacities[faces].min(dim=1).values  # TS+: a triangle is as opaque as its min
    with torch.no_grad():
        tri_cam = vertices.detach()[faces] @ R.detach().T + t.detach()
        keep = _visible(tri_cam, tri_opacity.detach(), sigma.detach(), intr, near)
        index = keep.nonzero().squeeze(1)
        order = torch.sort(tri_cam[index, :, 2].mean(dim=1), stable=True).indices
        index = index[order]
    fk = faces[index]
    p = vertices[fk] @ R.T + t  # (K, 3, 3) camera-frame vertices
    inv_z = 1.0 / p[..., 2]
    q = torch.stack([intr.fx * p[..., 0] * inv_z + intr.cx, intr.fy * p[..., 1] * inv_z + intr.cy], -1)
    d = q.roll(-1, dims=1) - q  # side j runs from vertex j to vertex j+1
    twice_area = d[:, 0, 0] * (-d[:, 2, 1]) - d[:, 0, 1] * (-d[:, 2, 0])
    side = torch.hypot(d[..., 0], d[..., 1])
    perimeter = side.sum(dim=1, keepdim=True)
    # l_j = b_{j+2} * perimeter / side_j, with b the barycentric weight of the vertex opposite
    # side j; it is 1 at the incentre and 0 on side j, so phi(p)/phi(s) = min_j l_j(p).
    scale = perimeter / (side * twice_area[:, None])
    a = -scale * d[..., 1]
    b = scale * d[..., 0]
    c = scale * (d[..., 1] * q[..., 0] - d[..., 0] * q[..., 1])
    lines = torch.stack([a, b, c], dim=-1).reshape(-1, 9)
    share = side / perimeter  # colour(p) = sum_j l_j(p) * share_j * colour of vertex j+2
    opposite = [2, 0, 1]
    color = (share[..., None] * colors[fk][:, opposite]).reshape(-1, 9)
    inv_depth = share * inv_z[:, opposite]
    normal = torch.linalg.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0])
    normal = normal / _length(normal, keepdim=True)
    with torch.no_grad():  # face the camera (at the origin)
        flip = torch.where((normal * p.mean(dim=1)).sum(dim=1) > 0, -1.0, 1.0).to(normal.dtype)
    normal = normal * flip[:, None]
    opacity, sig = tri_opacity[index], sigma[index]
    with torch.no_grad():
        support, bounds = _support_box(q.detach(), side.detach(), opacity.detach(), sig.detach(), intr)
    params = torch.cat(
        [lines, color, inv_depth, opacity[:, None], sig[:, None], normal, support[:, None]], dim=1
    )
    return ProjectedTriangles(params=params.contiguous(), bounds=bounds.contiguous(), index=index)
