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


class _PoseGradient(torch.autograd.Function):
    """The world-frame vertices ``(V, 3)`` as they are, giving the pose ``T_cam_world`` ``(4, 4)`` the
    gradient of the camera-frame vertices ``R v + t`` from the vertices' own: with ``g`` the gradient
    of the world-frame vertices under the pose, ``dL/dR = R Σ g vᵀ`` and ``dL/dt = R Σ g``. Two
    reductions over the vertices instead of moving all of them with autograd (which costs a matrix
    product forward and two backward: 9 ms a step at 47k triangles on 2 cores, against ~1 ms)."""

    @staticmethod
    def forward(ctx, vertices, T_cam_world):
        ctx.save_for_backward(vertices, T_cam_world)
        return vertices.view_as(vertices)

    @staticmethod
    def backward(ctx, d_vertices):
        vertices, T_cam_world = ctx.saved_tensors
        R = T_cam_world[:3, :3]
        d_pose = torch.zeros_like(T_cam_world)
        d_pose[:3, :3] = R @ (d_vertices.T @ vertices)  # render() holds the pose to the vertices' dtype
        d_pose[:3, 3] = R @ d_vertices.sum(dim=0)
        return d_vertices, d_pose


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
    if T_cam_world.requires_grad:  # pose gradients, from the vertices' (see _PoseGradient)
        vertices = _PoseGradient.apply(vertices, T_cam_world)
        T_cam_world = T_cam_world.detach()
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
