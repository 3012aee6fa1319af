"""The training objective (Eq. 3 of the method), term by term.

``L = (1-λ) L1 + λ D-SSIM + β1 L_opacity + β2 L_normal + β3 L_depth + β4 L_distortion``
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import cache
from types import ModuleType

import kornia
import torch
import torch.nn.functional as F
from torch import Tensor

from splat.config import TrainConfig
from splat.raster import RenderOutput
from splat.raster.extension import optional_cpu_extension


@dataclass
class LossTerms:
    """Each term as a 0-d tensor (unweighted) and the weighted total; the names are the keys of
    ``metrics.jsonl``'s ``loss`` (``depth`` is :func:`accumulated_depth_l1`, ``normal``
    :func:`normal_loss`)."""

    total: Tensor
    l1: Tensor
    dssim: Tensor
    depth: Tensor
    normal: Tensor
    opacity: Tensor
    distortion: Tensor
    exposure: Tensor
    pose: Tensor

    def as_floats(self) -> dict[str, float]:
        return {name: float(value.detach()) for name, value in self.__dict__.items()}


#: SSIM's window: the standard 11 x 11 Gaussian (size, sigma), applied as two 1-D passes.
SSIM_WINDOW = (11, 1.5)
SSIM_C1, SSIM_C2 = 0.01**2, 0.03**2


def _gaussian_blur(maps: Tensor) -> Tensor:
    """Each channel of ``(1, C, H, W)`` blurred by :data:`SSIM_WINDOW` (reflected borders), as one
    grouped convolution per axis."""
    window = _window(maps)
    channels, radius = maps.shape[1], SSIM_WINDOW[0] // 2
    # oneDNN convolves a channels-last image as it is; an NCHW one is copied into channel blocks
    # around every depthwise convolution (3x the time forward and backward at 320x240).
    maps = maps.contiguous(memory_format=torch.channels_last)
    along_x = window.view(1, 1, 1, -1).expand(channels, 1, 1, -1)
    along_y = window.view(1, 1, -1, 1).expand(channels, 1, -1, 1)
    # One padding for both passes: blurring reflected rows along x gives the reflected blurred rows.
    maps = F.pad(maps, [radius] * 4, mode="reflect")
    return F.conv2d(F.conv2d(maps, along_x, groups=channels), along_y, groups=channels)


def image_moments(image: Tensor) -> Tensor:
    """The local mean and mean square of a target ``(H, W, 3)`` image in SSIM's window, the two
    moments SSIM needs of it alone: ``(1, 6, H, W)`` (mean channels first), without gradient. A
    training view's are the same every time it is seen (1.5 ms a 320x240 view, 5.4 ms at 640x480)."""
    y = image.permute(2, 0, 1)[None]
    with torch.no_grad():
        return _gaussian_blur(torch.cat([y, y * y], dim=1)).contiguous()


def ssim_map(rendered: Tensor, target: Tensor, target_moments: Tensor | None = None) -> Tensor:
    """Per-pixel SSIM ``(H, W, 3)`` of two ``(H, W, 3)`` images in [0, 1], with the standard 11×11
    Gaussian window (σ = 1.5) and reflected borders: the values of ``kornia.metrics.ssim``.
    ``target_moments``: :func:`image_moments` of ``target`` when they are at hand.

    Float32 images on the CPU go through the CPU extension's fused kernel (``csrc/ssim_cpu.cpp``:
    forward+backward 2.2 instead of 7.2 ms an iteration in the room's training at 320x240, 9 instead
    of 34-43 ms at 640x480); others (CUDA, float64) through :func:`composed_ssim_map`, its
    specification.
    """
    moments = image_moments(target) if target_moments is None else target_moments
    kernel = _fused_kernel(rendered)
    if kernel is None or min(rendered.shape[:2]) <= SSIM_WINDOW[0] // 2:
        return composed_ssim_map(rendered, target, moments)
    x, y = (image.permute(2, 0, 1).contiguous() for image in (rendered, target))
    return _FusedSsim.apply(x, y, moments[0], _window(rendered), kernel).permute(1, 2, 0)


def composed_ssim_map(rendered: Tensor, target: Tensor, target_moments: Tensor) -> Tensor:
    """:func:`ssim_map` composed of PyTorch operations.

    Written out rather than calling kornia: kornia blurs the five local moments one call at a
    time and records the target's moments in the autograd graph. Here the three moments that
    involve the render are blurred in one grouped convolution and the target's two without
    gradient, in the channels-last layout the CPU convolutions are fast in; the same values and
    gradients.
    """
    x = rendered.permute(2, 0, 1)[None]
    y = target.permute(2, 0, 1)[None]
    # The blurs come out channels-last, each moment's channels interleaved with the others':
    # element-wise steps run faster on planes, after one copy.
    mu_y, yy = target_moments.split(3, dim=1)
    mu_x, xx, xy = _gaussian_blur(torch.cat([x, x * x, x * y], dim=1)).contiguous().split(3, dim=1)
    mu_xy, mu_x2, mu_y2 = mu_x * mu_y, mu_x * mu_x, mu_y * mu_y
    numerator = (2 * mu_xy + SSIM_C1) * (2 * (xy - mu_xy) + SSIM_C2)
    denominator = (mu_x2 + mu_y2 + SSIM_C1) * ((xx - mu_x2) + (yy - mu_y2) + SSIM_C2)
    return (numerator / (denominator + 1e-12))[0].permute(1, 2, 0)


def _window(like: Tensor) -> Tensor:
    """SSIM's 1-D window taps ``(11,)`` on ``like``'s device, in its dtype."""
    return _window_on(like.device, like.dtype)


@cache
def _window_on(device: torch.device, dtype: torch.dtype) -> Tensor:
    size, sigma = SSIM_WINDOW
    return kornia.filters.get_gaussian_kernel1d(size, sigma, device=device, dtype=dtype).view(-1)


def _fused_kernel(rendered: Tensor) -> ModuleType | None:
    """The CPU extension when its fused loss terms take ``rendered`` (float32 on the CPU) and it is
    built or buildable here, else None."""
    if rendered.device.type != "cpu" or rendered.dtype != torch.float32:
        return None
    return optional_cpu_extension()


class _FusedNormalLoss(torch.autograd.Function):
    """:func:`normal_loss` of rendered normals ``(H, W, 3)`` against a prior ``(H, W, 3)`` where
    alpha ``(H, W)`` shows a surface, by the CPU extension."""

    @staticmethod
    def forward(ctx, normal: Tensor, prior: Tensor, alpha: Tensor, kernel: ModuleType) -> Tensor:  # type: ignore[override]
        loss, count = kernel.normal_loss_forward(normal, prior, alpha)
        ctx.save_for_backward(normal, prior, alpha)
        ctx.kernel, ctx.count = kernel, int(count)
        return loss

    @staticmethod
    def backward(ctx, d_loss: Tensor) -> tuple[Tensor | None, ...]:  # type: ignore[override]
        normal, prior, alpha = ctx.saved_tensors
        return ctx.kernel.normal_loss_backward(d_loss, normal, prior, alpha, ctx.count), None, None, None


class _FusedSsim(torch.autograd.Function):
    """SSIM planes ``(3, H, W)`` of the render's planes ``x`` ``(3, H, W)`` against the target's
    ``y`` with its moments ``(6, H, W)``, by the CPU extension."""

    @staticmethod
    def forward(ctx, x: Tensor, y: Tensor, moments: Tensor, window: Tensor, kernel: ModuleType) -> Tensor:  # type: ignore[override]
        ssim, partials = kernel.ssim_forward(x, y, moments, window)
        ctx.save_for_backward(x, y, partials, window)
        ctx.kernel = kernel
        return ssim

    @staticmethod
    def backward(ctx, d_ssim: Tensor) -> tuple[Tensor | None, ...]:  # type: ignore[override]
        x, y, partials, window = ctx.saved_tensors
        return ctx.kernel.ssim_backward(d_ssim.contiguous(), x, y, partials, window), None, None, None, None


def masked_mean(values: Tensor, mask: Tensor) -> Tensor:
    """Mean of ``values`` ``(*S, ...)`` over the entries where ``mask`` ``(*S)`` bool is True
    (``values[mask].mean()``; ``mask`` must hold one at least), as sums over the whole tensor:
    indexing with a mask (a search for its pixels, a gather, and a scatter in the backward pass)
    took ~3 ms of an iteration's loss at 320x240."""
    extra = values.dim() - mask.dim()
    selected = torch.where(mask.view(*mask.shape, *([1] * extra)), values, 0.0)
    return selected.sum() / (mask.sum() * (values.numel() // mask.numel()))


def dssim(
    rendered: Tensor, target: Tensor, keep: Tensor | None = None, target_moments: Tensor | None = None
) -> Tensor:
    """``1 - SSIM`` (:func:`ssim_map`; mean over pixels, those where ``keep`` ``(H, W)`` bool is
    True when given) of two ``(H, W, 3)`` images in [0, 1]; ``target_moments``: as for
    :func:`ssim_map`."""
    values = ssim_map(rendered, target, target_moments)
    return 1.0 - (values.mean() if keep is None else masked_mean(values, keep))


def psnr_of_mse(mse: float) -> float:
    """PSNR (dB, peak 1) of a mean squared error, floored at 1e-12 (120 dB) so that a perfect
    match stays finite: how held-out views are scored during training."""
    return -10 * math.log10(max(mse, 1e-12))


def accumulated_depth_l1(out: RenderOutput, lidar_depth: Tensor, reference_m: float = math.inf) -> Tensor:
    """Mean ``|Σ w z - D_lidar| / max(1, D_lidar / reference_m)`` (metres) over pixels with a LiDAR
    return (``(H, W)``, 0 = none): returns beyond ``reference_m`` count their error relative to their
    range, as a pixel's footprint grows with it (outdoors, 50–80 m returns would otherwise outweigh
    everything else). The accumulated depth ``Σ w z`` is not divided by alpha, so a pixel whose
    LiDAR saw a surface is also pulled towards full coverage (a hole renders a depth near 0)."""
    valid = lidar_depth > 0
    if not bool(valid.any()):
        return out.accumulated_depth.new_zeros(())
    error = (out.accumulated_depth - lidar_depth).abs()
    return masked_mean(error / (lidar_depth / reference_m).clamp(min=1.0), valid)


def normal_loss(out: RenderOutput, prior: Tensor) -> Tensor:
    """Mean ``1 - <N_rendered, N_prior>`` over pixels with a prior (``(H, W, 3)``, 0 = none) that
    the render covers; rendered normals are normalised first.

    Float32 on the CPU goes through the CPU extension's fused kernel (``csrc/normal_loss_cpu.cpp``:
    forward+backward 0.5 instead of 2.4-3.2 ms at 320x240), others through
    :func:`composed_normal_loss`, its specification."""
    kernel = _fused_kernel(out.normal)
    if kernel is None:
        return composed_normal_loss(out, prior)
    alpha = out.alpha.detach().contiguous()
    return _FusedNormalLoss.apply(out.normal.contiguous(), prior.contiguous(), alpha, kernel)


def composed_normal_loss(out: RenderOutput, prior: Tensor) -> Tensor:
    """:func:`normal_loss` composed of PyTorch operations."""
    valid = (prior.abs().sum(dim=-1) > 0) & (out.alpha.detach() > 1e-3)
    if not bool(valid.any()):
        return out.alpha.new_zeros(())
    n = out.normal / out.normal.norm(dim=-1, keepdim=True).clamp(min=1e-8)
    return masked_mean(1.0 - (n * prior).sum(dim=-1), valid)


def training_loss(
    out: RenderOutput,
    image: Tensor,
    lidar_depth: Tensor | None,
    normal_prior: Tensor | None,
    opacity: Tensor,
    config: TrainConfig,
    moving_mask: Tensor | None = None,
    target_moments: Tensor | None = None,
    exposure_prior: Tensor | None = None,
    pose_prior: Tensor | None = None,
) -> LossTerms:
    """All loss terms of one view.

    Args:
        out: the render (``(H, W, ...)`` images).
        image: ``(H, W, 3)`` target in [0, 1].
        lidar_depth: ``(H, W)`` LiDAR depth or None (term skipped).
        normal_prior: ``(H, W, 3)`` normal prior or None (term skipped).
        opacity: ``(F,)`` activated triangle opacities; the regulariser averages those of the
            triangles this view sees (Adam would turn even a tiny constant gradient into full-size
            steps and fade out every triangle no view sees — geometry only the LiDAR saw).
        moving_mask: ``(H, W)`` bool, pixels of moving objects left out of L1 and D-SSIM, or None.
        target_moments: :func:`image_moments` of ``image`` when they are at hand (else computed).
        exposure_prior: the view's colour map's distance from the identity
            (:meth:`splat.exposure.ViewExposures.prior`), or None when the run learns no maps.
        pose_prior: the size of the view's pose correction
            (:meth:`splat.pose_corrections.PoseCorrections.prior`), or None when the run learns none.
    """
    zero = image.new_zeros(())
    keep = None if moving_mask is None or not bool(moving_mask.any()) else ~moving_mask
    error = (out.rgb - image).abs()
    l1 = error.mean() if keep is None else masked_mean(error, keep)
    ds = dssim(out.rgb, image, keep, target_moments) if config.lambda_dssim > 0 else zero
    depth = (
        accumulated_depth_l1(out, lidar_depth, config.depth_reference_m)
        if lidar_depth is not None and config.w_depth > 0
        else zero
    )
    normal = normal_loss(out, normal_prior) if normal_prior is not None and config.w_normal > 0 else zero
    in_view = out.max_weight > 0
    opacity_reg = masked_mean(opacity, in_view) if config.w_opacity > 0 and bool(in_view.any()) else zero
    distortion = out.distortion.mean() if config.w_distortion > 0 else zero
    exposure = zero if exposure_prior is None else exposure_prior
    pose = zero if pose_prior is None else pose_prior
    total = (
        (1 - config.lambda_dssim) * l1
        + config.lambda_dssim * ds
        + config.w_opacity * opacity_reg
        + config.w_normal * normal
        + config.w_depth * depth
        + config.w_distortion * distortion
        + config.w_exposure * exposure
        + config.w_pose * pose
    )
    return LossTerms(total, l1, ds, depth, normal, opacity_reg, distortion, exposure, pose)
