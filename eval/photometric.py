"""Photometric metrics on held-out views: PSNR, SSIM and (when its weights are on this machine) LPIPS.

Images are float tensors in [0, 1] of shape ``(3, H, W)`` or ``(B, 3, H, W)``; numpy arrays are
accepted too (``(H, W, 3)`` uint8 or float).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path
from typing import Literal

import numpy as np
import torch
import torch.nn.functional as F

from eval.lpips_net import MIN_SIDE, LpipsAlex
from eval.lpips_weights import HOW_TO_GET, load_lpips
from rig.errors import InputError

#: SSIM window as in 3DGS evaluation (and scikit-image with ``gaussian_weights=True``).
SSIM_WINDOW = 11
SSIM_SIGMA = 1.5
_C1 = 0.01**2
_C2 = 0.03**2


def as_image_tensor(image: np.ndarray | torch.Tensor) -> torch.Tensor:
    """``(B, C, H, W)`` float64 tensor in [0, 1] from a tensor ``(C, H, W)``/``(B, C, H, W)`` in
    [0, 1] or a numpy image ``(H, W)``/``(H, W, C)`` (uint8 → divided by 255)."""
    if isinstance(image, np.ndarray):
        array = image.astype(np.float64) / 255.0 if image.dtype == np.uint8 else image.astype(np.float64)
        if array.ndim == 2:
            array = array[:, :, None]
        tensor = torch.from_numpy(np.ascontiguousarray(array.transpose(2, 0, 1)))
    else:
        tensor = image.to(torch.float64)
    if tensor.ndim == 3:
        tensor = tensor.unsqueeze(0)
    if tensor.ndim != 4:
        raise InputError(
            f"expected an image of shape (C, H, W) or (B, C, H, W), got {tuple(tensor.shape)}", field="images"
        )
    return tensor


def _check_pair(a: torch.Tensor, b: torch.Tensor) -> None:
    """Same shape, not empty, finite: a metric of NaN pixels would be NaN, one of no pixels a
    mean of nothing (NaN too) — both are input errors, never numbers to report."""
    if a.shape != b.shape:
        raise InputError(f"images differ in shape: {tuple(a.shape)} vs {tuple(b.shape)}", field="images")
    if a.numel() == 0:
        raise InputError(f"image is empty (shape {tuple(a.shape)})", field="images")
    for name, image in (("rendered", a), ("target", b)):
        if not bool(torch.isfinite(image).all()):
            raise InputError("image holds NaN or Inf", field=name)


def psnr(
    rendered: np.ndarray | torch.Tensor,
    target: np.ndarray | torch.Tensor,
    mask: np.ndarray | torch.Tensor | None = None,
) -> float:
    """Peak signal-to-noise ratio in dB for data range 1 (``math.inf`` for identical images,
    never NaN: empty or non-finite images raise :class:`~rig.errors.InputError`); with ``mask``
    ``(H, W)`` bool, over the pixels where it is True only (none: an InputError)."""
    a, b = as_image_tensor(rendered), as_image_tensor(target)
    _check_pair(a, b)
    diff = a - b
    if mask is not None:
        keep = torch.as_tensor(mask, dtype=torch.bool, device=diff.device)
        if keep.shape != diff.shape[-2:]:
            raise InputError(f"mask of shape {tuple(keep.shape)} for images of {tuple(diff.shape[-2:])}",
                             field="mask")  # fmt: skip
        if not bool(keep.any()):
            raise InputError("the mask selects no pixel", field="mask")
        diff = diff[..., keep]
    peak = float(diff.abs().max())
    if peak == 0.0:
        return math.inf
    # -10 log10(mean(d^2)) with the largest |d| taken out first: the squares of differences
    # below ~1e-154 underflow to 0, which made two different images "identical" (inf dB).
    return -20.0 * math.log10(peak) - 10.0 * math.log10(float(torch.mean((diff / peak) ** 2)))


def color_aligned(rendered: np.ndarray, target: np.ndarray) -> np.ndarray:
    """The ``(H, W, 3)`` float render in [0, 1] mapped by the 3×3 colour matrix (a gain per channel
    and their mixing: exposure and white balance) that best fits it to ``target`` ``(H, W, 3)`` in
    the least-squares sense, clipped to [0, 1]: the render with the test image's exposure, which no
    method can know from training (:mod:`splat.exposure`). Black pixels (holes) stay black and do
    not change the fit."""
    samples = rendered.reshape(-1, 3).astype(np.float64)
    matrix = np.linalg.lstsq(samples, target.reshape(-1, 3).astype(np.float64), rcond=None)[0]  # (3, 3)
    return np.clip(samples @ matrix, 0.0, 1.0).reshape(rendered.shape).astype(rendered.dtype)


def _gaussian_window(dtype: torch.dtype, device: torch.device) -> torch.Tensor:
    x = torch.arange(SSIM_WINDOW, dtype=dtype, device=device) - SSIM_WINDOW // 2
    g = torch.exp(-(x**2) / (2 * SSIM_SIGMA**2))
    return g / g.sum()


def ssim_map(a: torch.Tensor, b: torch.Tensor) -> torch.Tensor:
    """Per-pixel SSIM ``(B, C, H, W)`` of images ``(B, C, H, W)`` in [0, 1], 11×11 Gaussian window
    (σ = 1.5) applied separably with zero padding, as 3DGS's training loss computes it."""
    g = _gaussian_window(a.dtype, a.device)
    channels = a.shape[1]
    gx = g.view(1, 1, 1, -1).expand(channels, 1, 1, -1)
    gy = g.view(1, 1, -1, 1).expand(channels, 1, -1, 1)
    pad = SSIM_WINDOW // 2

    def blur(x: torch.Tensor) -> torch.Tensor:
        x = F.conv2d(x, gx, padding=(0, pad), groups=channels)
        return F.conv2d(x, gy, padding=(pad, 0), groups=channels)

    mu_a, mu_b = blur(a), blur(b)
    var_a = blur(a * a) - mu_a**2
    var_b = blur(b * b) - mu_b**2
    cov = blur(a * b) - mu_a * mu_b
    return ((2 * mu_a * mu_b + _C1) * (2 * cov + _C2)) / ((mu_a**2 + mu_b**2 + _C1) * (var_a + var_b + _C2))


def ssim(
    rendered: np.ndarray | torch.Tensor,
    target: np.ndarray | torch.Tensor,
    border: Literal["crop", "zero-pad"] = "crop",
) -> float:
    """Mean SSIM (data range 1, 11×11 Gaussian window, σ = 1.5).

    ``border="crop"`` (default) averages only pixels whose window lies inside the image, as
    scikit-image's ``structural_similarity(gaussian_weights=True, sigma=1.5,
    use_sample_covariance=False, data_range=1)`` does; ``"zero-pad"`` averages every pixel with
    zero-padded windows, as the 3DGS evaluation scripts do (the two differ only near borders).
    """
    a, b = as_image_tensor(rendered), as_image_tensor(target)
    _check_pair(a, b)
    values = ssim_map(a, b)
    if border == "crop":
        pad = SSIM_WINDOW // 2
        if a.shape[-1] <= 2 * pad or a.shape[-2] <= 2 * pad:
            raise InputError(
                f"image {tuple(a.shape[-2:])} is smaller than the {SSIM_WINDOW}x{SSIM_WINDOW} window",
                field="images",
            )
        values = values[..., pad:-pad, pad:-pad]
    elif border != "zero-pad":
        raise InputError(f"unknown border mode {border!r}; expected crop or zero-pad", field="border")
    return float(values.mean())


@dataclass(frozen=True)
class LpipsResult:
    """LPIPS distance, or ``value=None`` with the reason it could not be computed."""

    value: float | None
    reason: str = ""


def lpips(
    rendered: np.ndarray | torch.Tensor,
    target: np.ndarray | torch.Tensor,
    weights: str | Path | LpipsAlex | None = None,
) -> LpipsResult:
    """LPIPS v0.1 "alex" distance (mean over the batch; :mod:`eval.lpips_net`).

    ``weights``: a loaded network, a weights file, or ``None`` for the places
    :func:`eval.lpips_weights.load_lpips` looks at. Never downloads: without weights, returns
    ``value=None`` with the reason saying how to get them (never 0, never a random network).
    A weights file that is not LPIPS weights raises :class:`~rig.errors.InputError`.
    """
    network = weights if isinstance(weights, LpipsAlex) else load_lpips(weights)
    if network is None:
        return LpipsResult(None, HOW_TO_GET)
    a, b = as_image_tensor(rendered).float(), as_image_tensor(target).float()
    _check_pair(a, b)
    if a.shape[1] != 3 or min(a.shape[-2:]) < MIN_SIDE:
        raise InputError(
            f"LPIPS needs RGB images of at least {MIN_SIDE}x{MIN_SIDE} pixels, got {tuple(a.shape[1:])}",
            field="images",
        )
    with torch.no_grad():
        return LpipsResult(float(network(a, b).mean()))
