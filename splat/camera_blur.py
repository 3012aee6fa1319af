"""The camera's blur: a Gaussian point-spread function the renders pass through before they are
compared with the captured images.

The images the training sees are softer than a point-sampled render: ``lts prepare`` resamples
every distorted image bilinearly into the pinhole camera (a shift of f px weighs two neighbours
by f and 1 - f, a blur of variance f (1 - f)), and a real camera adds its optics and demosaicing.
Opaque triangles with sharp edges cannot make that blur themselves. One width per camera is
fitted on the training views once the triangles are trained (:func:`fit_blur`), so it is a
property of the camera, measured like the colour maps of :mod:`splat.exposure`, and the test
views are rendered through it (:func:`blurred`). A render without blur is the width 0.
"""

from __future__ import annotations

import math
from collections.abc import Iterable
from pathlib import Path

import torch
from kornia.filters import get_gaussian_kernel1d
from scipy.optimize import minimize_scalar
from torch import Tensor

from rig.errors import InputError
from splat.losses import psnr_of_mse

#: The widest blur (Gaussian sigma, px) :func:`fit_blur` considers.
MAX_WIDTH_PX = 1.5
#: How many training views (evenly spread) :func:`fit_blur` fits on: one number needs few pixels.
FIT_VIEWS = 12


def blurred(rgb: Tensor, sigma_px: float) -> Tensor:
    """``rgb`` ``(H, W, 3)`` through a Gaussian of ``sigma_px`` pixels (3 sigma wide, borders
    replicated); the same tensor for a width of 0. Differentiable in ``rgb``."""
    if sigma_px <= 0:
        return rgb
    radius = max(1, math.ceil(3 * sigma_px))
    taps = get_gaussian_kernel1d(2 * radius + 1, sigma_px, device=rgb.device, dtype=rgb.dtype).view(-1)
    out = rgb
    # Separable, as sums of shifted slices: at the widths fitted (0.5-0.8 px, 5-7 taps) they run
    # 1.3-2x faster than the channels-last grouped convolution splat.losses blurs SSIM's 11 taps with
    # (as fast at 1.4 px), and the two blurs differ in their borders too.
    for dim in (0, 1):
        n = out.shape[dim]
        rows = torch.arange(-radius, n + radius, device=rgb.device).clamp(0, n - 1)
        padded = out.index_select(dim, rows)
        out = sum(taps[i] * padded.narrow(dim, i, n) for i in range(2 * radius + 1))
    return out


def summary_width_px(summary: dict, path: Path) -> float:
    """The width (px) a run fitted: ``camera_blur.width_px`` of its ``summary.json`` at ``path``
    (read as ``summary``); 0 for a run from before the blur was fitted. InputError for anything but
    a number from 0 to 100."""
    blur = summary.get("camera_blur") or {}
    width = blur.get("width_px", 0.0) if isinstance(blur, dict) else blur
    if isinstance(width, bool) or not isinstance(width, int | float) or not 0 <= width < 100:
        raise InputError(
            f"expected a width in pixels (0 to 100), got {width!r}", path=path, field="camera_blur.width_px"
        )
    return float(width)


@torch.no_grad()
def fit_blur(views: Iterable[tuple[Tensor, Tensor, Tensor | None]]) -> tuple[float, float, float]:
    """The width (px, 0 to :data:`MAX_WIDTH_PX`, to 0.01 px) whose blur brings the renders nearest
    their images in squared error.

    Args:
        views: per view its render ``(H, W, 3)`` (as scored: through its colour map), its image
            ``(H, W, 3)`` and the mask ``(H, W)`` of the pixels to leave out (moving objects), or None.

    Returns:
        The width (px), and the PSNR (dB) of the renders without blur and with it (NaN without a
        pixel to fit on).
    """
    pairs = []
    for render, image, left_out in views:
        keep = torch.ones_like(image[..., :1]) if left_out is None else (~left_out)[..., None].to(image.dtype)
        pairs.append((render, image, keep))
    count = 3 * sum(float(keep.sum()) for *_, keep in pairs)
    if count == 0:
        return 0.0, math.nan, math.nan

    def mean_square(width: float) -> float:
        total = 0.0
        for render, image, keep in pairs:
            total += float((((blurred(render, width).clamp(0, 1) - image) ** 2) * keep).sum())
        return total / count

    sharp = mean_square(0.0)
    search = minimize_scalar(
        mean_square, bounds=(0.0, MAX_WIDTH_PX), method="bounded", options={"xatol": 0.005}
    )
    width, fitted = round(float(search.x), 2), float(search.fun)
    if fitted >= sharp:
        width, fitted = 0.0, sharp
    return width, psnr_of_mse(sharp), psnr_of_mse(fitted)
