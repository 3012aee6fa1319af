"""Where the background shows: the image rows above the LiDAR's topmost return.

Composited everywhere, the background would also fill gaps between triangles with a plausible
colour, and the photometric loss would stop pulling triangles into them (indoors that leaves more
holes). Above the highest LiDAR return of an image column is what the LiDAR did not reach: sky,
far or tall structure above its field. Below it, a gap in the triangles stays black in training.

Scored renders (test views in training, ``lts eval``) use the same rule for every method, so a
hole in the geometry below the LiDAR's reach still counts as a hole in PSNR; free renders (the
viewer) composite the background wherever the triangles leave it visible.
"""

from __future__ import annotations

import torch
import torch.nn.functional as F
from torch import Tensor

#: The topmost return is taken over this fraction of the image width around each column (a sparse
#: scan leaves columns without a return on its highest ring).
WINDOW_FRACTION = 0.05


def above_lidar(depth: Tensor) -> Tensor:
    """``(H, W)`` bool: pixels above every LiDAR return of ``depth`` ``(H, W)`` (0 = none) in their
    column and the columns within ``WINDOW_FRACTION`` of the width around it."""
    height, width = depth.shape
    rows = torch.arange(height, device=depth.device)[:, None]
    top = torch.where(depth > 0, rows, height).amin(dim=0).to(depth.dtype)  # (W,), H: no return
    k = max(1, round(width * WINDOW_FRACTION)) | 1
    top = -F.max_pool1d(-top[None, None], k, stride=1, padding=k // 2)[0, 0]  # the highest nearby
    return rows < top[None, :]


def scored_background_mask(depth: Tensor | None) -> Tensor | None:
    """``(H, W)`` bool mask of :func:`above_lidar` for a view with LiDAR depth ``(H, W)``, or None
    (the background everywhere) for a view without."""
    return None if depth is None or not bool((depth > 0).any()) else above_lidar(depth)
