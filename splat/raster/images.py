"""What a rasteriser backend returns (before mapping triangle ids back to the caller's faces)."""

from __future__ import annotations

from typing import NamedTuple

from torch import Tensor


class RasterImages(NamedTuple):
    """Per-pixel and per-triangle outputs of one backend; ``H, W`` image size, ``K`` triangles.

    rgb ``(H, W, 3)`` (premultiplied, black background), accumulated_depth ``(H, W)`` = sum w z,
    alpha ``(H, W)`` = sum w, normal ``(H, W, 3)`` = sum w n, median ``(H, W)`` depth of the last
    pair composited while the transmittance was still above 0.5 (0 if none), distortion
    ``(H, W)`` 2DGS depth distortion, dominant ``(H, W)`` int64 row of the sorted triangles with
    the largest weight (-1 if none), max_weight ``(K,)`` largest weight per row. The exact
    semantics are in :mod:`splat.raster.reference`.
    """

    rgb: Tensor
    accumulated_depth: Tensor
    alpha: Tensor
    normal: Tensor
    median: Tensor
    distortion: Tensor
    dominant: Tensor
    max_weight: Tensor
