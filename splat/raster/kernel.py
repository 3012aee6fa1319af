"""Autograd wrapper around a compiled rasteriser (CPU or CUDA extension: the same interface)."""

from __future__ import annotations

from types import ModuleType

import torch
from torch import Tensor

from splat.raster.binning import TileBins
from splat.raster.images import RasterImages


class _Rasterize(torch.autograd.Function):
    @staticmethod
    def forward(
        ctx, params: Tensor, bounds: Tensor, bins: TileBins, width: int, height: int, ext: ModuleType
    ):
        geometry = (bounds, bins.tile_offsets, bins.tile_slots, bins.slot_tri, bins.tri_offsets)
        (rgb, depth, alpha, normal, median, distortion, dominant, max_weight, transmittance, last,
         median_entry) = ext.forward(params, *geometry, width, height)  # fmt: skip
        ctx.save_for_backward(params, *geometry, alpha, depth, distortion, transmittance, last, median_entry)
        ctx.size, ctx.ext = (width, height), ext
        ctx.mark_non_differentiable(dominant, max_weight)
        return rgb, depth, alpha, normal, median, distortion, dominant, max_weight

    @staticmethod
    def backward(ctx, d_rgb, d_depth, d_alpha, d_normal, d_median, d_distortion, _dom, _mw):
        params, *geometry, alpha, depth, distortion, transmittance, last, median_entry = ctx.saved_tensors
        grads = [g.contiguous() for g in (d_rgb, d_depth, d_alpha, d_normal, d_median, d_distortion)]
        d_params = ctx.ext.backward(
            params, *geometry, *ctx.size, alpha, depth, distortion, transmittance, last, median_entry, *grads
        )
        return d_params, None, None, None, None, None


def rasterize_kernel(
    params: Tensor, bounds: Tensor, bins: TileBins, width: int, height: int, ext: ModuleType
) -> RasterImages:
    """Rasterise sorted triangle parameters ``(K, 27)`` with a compiled extension."""
    return RasterImages(*_Rasterize.apply(params, bounds, bins, width, height, ext))
