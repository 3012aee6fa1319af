"""Where the background shows: where the LiDAR reached nothing.

Composited everywhere, the background would also fill gaps between triangles with a plausible
colour, and the photometric loss would stop pulling triangles into them (indoors that leaves more
holes). So it shows only where the LiDAR reached nothing: above the highest return of an image
column (sky, far or tall structure above its field), and in windows of the image with no return
between returns above and below (sky or far structure under an overpass or between two roofs,
beyond the LiDAR's range). Elsewhere a gap in the triangles stays black in training.

Scored renders (test views in training, ``lts eval``) use the same rule for every method, so a
hole in the geometry where the LiDAR saw a surface still counts as a hole in PSNR; free renders
(the viewer) composite the background wherever the triangles leave it visible.
"""

from __future__ import annotations

import math

import torch
import torch.nn.functional as F
from torch import Tensor

#: The topmost return is taken over this fraction of the image width around each column (a sparse
#: scan leaves columns without a return on its highest ring).
WINDOW_FRACTION = 0.05

#: A square window of the image this wide with no return in it lies beyond the LiDAR's range: over
#: four rings of a 64-beam spinning LiDAR (0.33-0.5° apart), 1.5 of a 32-beam one.
EMPTY_WINDOW_DEG = 2.0


def above_lidar(depth: Tensor) -> Tensor:
    """``(H, W)`` bool: pixels above every LiDAR return of ``depth`` ``(H, W)`` (0 = none) in their
    column and the columns within ``WINDOW_FRACTION`` of the width around it."""
    height, width = depth.shape
    rows = torch.arange(height, device=depth.device, dtype=torch.float32)[:, None]
    top = torch.where(depth > 0, rows, float(height)).amin(dim=0)  # (W,), H: no return
    highest_nearby = -_pool_columns(-top, max(1, round(width * WINDOW_FRACTION)) | 1)
    return rows < highest_nearby[None, :]


def beyond_range(depth: Tensor, focal_px: float, unknown: Tensor | None = None) -> Tensor:
    """``(H, W)`` bool: pixels within ``EMPTY_WINDOW_DEG`` squares without a return of ``depth``
    ``(H, W)`` (0 = none) that lie below :func:`above_lidar`'s pixels and above the lowest return of
    every column near them (not below the LiDAR's field). ``focal_px`` is the camera's focal length
    in pixels; pixels True in ``unknown`` ``(H, W)`` bool (moving objects, whose returns were taken
    out) count as returns."""
    k = max(3, round(focal_px * math.tan(math.radians(EMPTY_WINDOW_DEG)))) | 1
    seen = depth > 0 if unknown is None else (depth > 0) | unknown
    height = seen.shape[0]
    rows = torch.arange(height, device=depth.device, dtype=torch.float32)[:, None]
    bottom = torch.where(seen, rows, -1.0).amax(dim=0)  # (W,)
    bottom = torch.where(seen.any(dim=0), bottom, float(height))  # a column without returns: no limit
    highest_bottom = -_pool_columns(-bottom, k)
    inside = (rows < highest_bottom[None, :]) & ~above_lidar(depth)
    empty = _dilate(seen, k).logical_not()
    return _dilate(empty & inside, k)


def scored_background_mask(
    depth: Tensor | None, focal_px: float, unknown: Tensor | None = None
) -> Tensor | None:
    """``(H, W)`` bool: where the background shows in a view with LiDAR depth ``(H, W)``
    (:func:`above_lidar` or :func:`beyond_range`), or None (everywhere) for a view without."""
    if depth is None or not bool((depth > 0).any()):
        return None
    return above_lidar(depth) | beyond_range(depth, focal_px, unknown)


def _pool_columns(values: Tensor, k: int) -> Tensor:
    """``(W,)``: the largest of ``values`` ``(W,)`` over ``k`` columns (odd) around each column."""
    return F.max_pool1d(values[None, None], k, stride=1, padding=k // 2)[0, 0]


def _dilate(mask: Tensor, k: int) -> Tensor:
    """``(H, W)`` bool: ``mask`` dilated by a ``k`` × ``k`` square (odd ``k``), as a ``k``-wide row
    then a ``k``-high column (the square's maximum is the column's of the rows': 2k comparisons a
    pixel instead of k²: 1.6x faster at k = 11 on a 640x240 image)."""
    rows = F.max_pool2d(mask[None, None].float(), (1, k), stride=1, padding=(0, k // 2))
    return F.max_pool2d(rows, (k, 1), stride=1, padding=(k // 2, 0))[0, 0] > 0
