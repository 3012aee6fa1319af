"""Per-triangle set-up on a compiled extension: the same result as
:func:`splat.raster.project.project_triangles` (its specification), in one pass per triangle."""

from __future__ import annotations

from types import ModuleType

import torch
from torch import Tensor

from splat.raster.project import Intrinsics, ProjectedTriangles


class _Setup(torch.autograd.Function):
    @staticmethod
    def forward(ctx, vertices, colors, opacities, sigma, faces, kept, rank, view, size, ext):
        inputs = [t.contiguous() for t in (vertices, faces, colors, opacities)]
        params, bounds = ext.setup_forward(*inputs, sigma.contiguous(), kept, rank, view, *size)
        ctx.save_for_backward(*inputs, kept, rank, view)
        ctx.size, ctx.ext, ctx.n_faces = size, ext, len(faces)
        ctx.mark_non_differentiable(bounds)
        return params, bounds

    @staticmethod
    def backward(ctx, d_params, _d_bounds):
        *inputs, kept, rank, view = ctx.saved_tensors
        d_vertices, d_colors, d_opacities, d_sigma = ctx.ext.setup_backward(
            *inputs, kept, rank, view, *ctx.size, d_params.contiguous(), ctx.n_faces
        )
        return d_vertices, d_colors, d_opacities, d_sigma, None, None, None, None, None, None


def project_triangles_kernel(
    vertices: Tensor,
    faces: Tensor,
    colors: Tensor,
    opacities: Tensor,
    sigma: Tensor,
    T_cam_world: Tensor,
    intr: Intrinsics,
    near: float,
    ext: ModuleType,
) -> ProjectedTriangles:
    """Arguments and result as :func:`~splat.raster.project.project_triangles`."""
    if T_cam_world.requires_grad:  # pose gradients: move to the camera frame with autograd first
        vertices = vertices @ T_cam_world[:3, :3].T + T_cam_world[:3, 3]
        T_cam_world = torch.eye(4, dtype=vertices.dtype, device=vertices.device)
    pose = T_cam_world.detach().to("cpu", torch.float64)
    view = torch.cat(
        [
            pose[:3, :3].flatten(),
            pose[:3, 3],
            torch.tensor([intr.fx, intr.fy, intr.cx, intr.cy, near], dtype=torch.float64),
        ]
    ).to(vertices.device)
    size = (intr.width, intr.height)
    with torch.no_grad():
        keep, key = ext.setup_cull(
            vertices.detach().contiguous(), faces.contiguous(), opacities.detach().contiguous(),
            sigma.detach().contiguous(), view, *size,
        )  # fmt: skip
        kept = keep.nonzero().squeeze(1)
        # Kept keys are depths > near > 0, whose IEEE bit patterns sort like the values: sorting
        # them as integers takes PyTorch's radix sort (~10x faster than a float sort).
        bits = torch.int32 if key.dtype == torch.float32 else torch.int64
        order = torch.sort(key[kept].view(bits), stable=True).indices
        rank = torch.empty_like(order)
        rank[order] = torch.arange(len(order), device=order.device)
    params, bounds = _Setup.apply(vertices, colors, opacities, sigma, faces, kept, rank, view, size, ext)
    return ProjectedTriangles(params=params, bounds=bounds, index=kept[order])
