"""Exposure and white balance: a colour matrix learned for each training view.

A real camera changes its gain and white balance from frame to frame (auto-exposure): the same
wall is brighter in one image than in the next. Fitting one colour per triangle to all of them
averages the differences into the triangles and the loss keeps pulling them back and forth. As
splatting trainers do for real captures, each training view's render is mapped by its own colour
transform ``rgb' = A rgb`` (``A`` ``(3, 3)``: a gain per channel and their mixing, which is white
balance) before the photometric loss, and a prior pulls every map towards the identity, so the
triangles keep the images' common appearance and the maps take up only what differs per image.

A gain in linear light is the same gain after the camera's gamma curve, so no offset is needed,
and none is learnt: a render is black where no triangle covers a pixel, and an offset per view
learnt to lift those holes to the images' mean colour (on the virtual street +0.24 in every
view), which darkened every triangle by as much.

A held-out image's own map is not known to training, but a camera's exposure drifts smoothly
in time, and so do the maps (on the virtual street without exposure changes they took up a
smooth drift of up to 9 % over the drive): a test view gets the map interpolated in time between
the training views before and after it, when that predicts the training views' own maps better
than the identity does (each left out in turn; :func:`held_out_maps`). Where it does not (a gain
that jumps from frame to frame), the test image's gain is measured against the nearest training
image's on the LiDAR points both see (:func:`log_gain`, as a camera's metadata would tell it,
from the images alone and not the render) and its map is that image's scaled by it; the
identity where it cannot be measured.
Exported meshes keep the triangles' own colours. ``lts eval`` applies the test views' maps
(``RUN_DIR/exposure.json``) and reports, beside that PSNR, one after fitting each test view's
colour matrix to its image (:func:`eval.photometric.color_aligned`), the same for every method.
"""

from __future__ import annotations

import math

import numpy as np
import torch
from torch import Tensor

from rig.transforms import transform_points
from splat.camera_only import in_view

#: How the test views' maps were chosen (``exposure.json``'s ``test_views``).
INTERPOLATED = "interpolated in time between the training views before and after"
IDENTITY = "the identity (interpolation did not predict the training views' maps)"
MEASURED = (
    "the nearest training view's map scaled by the test image's gain against its image, measured on "
    "the LiDAR points both see ({} of {} views; the identity for the rest)"
)


class ViewExposures:
    """The colour maps of ``n_views`` training views, stored as their offsets from the identity
    ``(V, 3, 3)`` (``A - I``; zeros: every map the identity), a leaf that requires grad."""

    def __init__(self, offsets: Tensor):
        if offsets.dim() != 3 or offsets.shape[1:] != (3, 3):
            raise ValueError(f"expected colour-map offsets of shape (V, 3, 3), got {tuple(offsets.shape)}")
        self.offsets = offsets.detach().clone().requires_grad_(True)

    @classmethod
    def identity(cls, n_views: int, dtype: torch.dtype = torch.float32, device: str = "cpu") -> ViewExposures:
        return cls(torch.zeros(n_views, 3, 3, dtype=dtype, device=device))

    def apply(self, rgb: Tensor, view: int) -> Tensor:
        """``(H, W, 3)`` render ``rgb`` mapped by view ``view``'s colour transform."""
        return rgb + rgb @ self.offsets[view].T

    def prior(self, view: int) -> Tensor:
        """Squared distance of view ``view``'s map from the identity (sum over its 9 numbers)."""
        return self.offsets[view].square().sum()

    def gains(self) -> Tensor:
        """``(V,)`` each map's mean gain (the mean of ``A``'s diagonal)."""
        return 1.0 + self.offsets.detach().diagonal(dim1=1, dim2=2).mean(dim=1)

    def summary(self) -> dict[str, float]:
        """The spread of the learnt maps: the smallest and largest mean gain and the largest
        mixing between channels (off-diagonal entry of ``A``) over the views."""
        offsets = self.offsets.detach()
        if len(offsets) == 0:
            return {"gain_min": 1.0, "gain_max": 1.0, "mixing_max": 0.0}
        mixing = (offsets - torch.diag_embed(offsets.diagonal(dim1=1, dim2=2))).abs().amax()
        gains = self.gains()
        return {
            "gain_min": round(float(gains.min()), 4),
            "gain_max": round(float(gains.max()), 4),
            "mixing_max": round(float(mixing), 4),
        }


def through_color_map(rgb: Tensor, matrix: Tensor | None) -> Tensor:
    """A render ``(H, W, 3)`` seen through a colour ``matrix`` ``(3, 3)`` (None: as it is), clipped
    to [0, 1]: how a held-out view is scored."""
    return (rgb if matrix is None else rgb @ matrix.to(rgb).T).clamp(0, 1)


def interpolated(offsets: Tensor, times: np.ndarray, at: np.ndarray) -> Tensor:
    """Map offsets ``(Q, 3, 3)`` at times ``at`` ``(Q,)``, linear in time between the offsets
    ``(V, 3, 3)`` of the views at ``times`` ``(V,)`` before and after (the nearest beyond the ends)."""
    order = np.argsort(times)
    flat = offsets.detach().cpu().double().numpy()[order].reshape(len(order), 9)
    values = np.stack([np.interp(at, times[order], flat[:, k]) for k in range(9)], axis=1)
    return torch.as_tensor(values.reshape(-1, 3, 3), dtype=offsets.dtype)


def interpolation_predicts(offsets: Tensor, times: np.ndarray) -> bool:
    """Whether the training views' maps ``(V, 3, 3)`` (at ``times`` ``(V,)``) are, summed over the
    views between the first and the last, closer to the map interpolated from the others (each left
    out in turn) than to the identity."""
    if len(times) < 3:
        return False
    order = np.argsort(times)
    interpolation_error, identity_error = 0.0, 0.0
    for i in order[1:-1]:
        others = np.flatnonzero(np.arange(len(times)) != i)
        predicted = interpolated(offsets[others], times[others], times[i : i + 1])[0]
        interpolation_error += float((offsets[i].detach().cpu() - predicted).square().sum())
        identity_error += float(offsets[i].detach().square().sum())
    return interpolation_error < identity_error


def held_out_maps(
    exposures: ViewExposures,
    train_times: np.ndarray,
    test_times: np.ndarray,
    measured: tuple[np.ndarray, np.ndarray] | None = None,
) -> tuple[Tensor, str]:
    """The colour matrices ``(Q, 3, 3)`` (``A``, not offsets) of held-out views at ``test_times``
    ``(Q,)`` from the training views' maps (at ``train_times`` ``(V,)``), and how they were chosen:
    :data:`INTERPOLATED`; else, with ``measured`` (per held-out view the index of its nearest
    training view ``(Q,)`` and the log of its image's gain against that view's ``(Q,)``, NaN where
    not measured: :func:`log_gain`), :data:`MEASURED`; else :data:`IDENTITY`."""
    eye = torch.eye(3, dtype=exposures.offsets.dtype)
    if interpolation_predicts(exposures.offsets, train_times):
        return eye + interpolated(exposures.offsets, train_times, test_times), INTERPOLATED
    maps = eye.expand(len(test_times), 3, 3).clone()
    if measured is None or not np.isfinite(measured[1]).any():
        return maps, IDENTITY
    nearest, log_gains = measured
    known = np.isfinite(log_gains)
    gains = torch.as_tensor(np.exp(log_gains[known]), dtype=eye.dtype)[:, None, None]
    maps[known] = gains * (eye + exposures.offsets.detach().cpu()[nearest[known]])
    return maps, MEASURED.format(int(known.sum()), len(known))


def grey(image: np.ndarray) -> np.ndarray:
    """The grey level ``(H, W)`` of an RGB image ``(H, W, 3)``: the mean of its channels."""
    return image.mean(axis=2)


def log_gain(
    before: np.ndarray,
    after: np.ndarray,
    points: np.ndarray,
    camera,
    T_world_before: np.ndarray,
    T_world_after: np.ndarray,
) -> float | None:
    """Log brightness ratio of grey image ``after`` to grey image ``before`` (``(H, W)`` in [0, 1],
    :func:`grey`; seen from ``T_world_before`` / ``T_world_after`` ``(4, 4)``) at ``points``
    ``(M, 3)`` (the camera-frame LiDAR returns of ``before``): the median over the points both
    images see of ``log(grey_after / grey_before)``; None where fewer than
    :data:`MIN_SHARED_POINTS` are shared or fewer than :data:`MIN_AGREEING_FRACTION` of them agree
    with it. A surface keeps its colour from one image to the next, so what differs is the
    camera's gain."""
    world = transform_points(T_world_before, points)
    grey_before, grey_after = (
        _sampled(image, world, camera, T) for image, T in ((before, T_world_before), (after, T_world_after))
    )
    usable = np.isfinite(grey_before) & np.isfinite(grey_after) & (grey_before > 0.04) & (grey_after > 0.04)
    usable &= (grey_before < 0.96) & (grey_after < 0.96)
    if usable.sum() < MIN_SHARED_POINTS:
        return None
    logs = np.log(grey_after[usable] / grey_before[usable])
    median = float(np.median(logs))
    # A gain moves every point alike; points the next image sees something else at (an
    # occluder, a turn) scatter, and can pull the median of a few pairs far off.
    if np.mean(np.abs(logs - median) <= GAIN_AGREEMENT) < MIN_AGREEING_FRACTION:
        return None
    return median


def neighbour_gains(
    images: list[np.ndarray], lidar_points: list[np.ndarray], poses_world_cam: np.ndarray, camera
) -> np.ndarray:
    """``(K - 1,)`` :func:`log_gain` of each image to the one before (``images``: ``(H, W, 3)`` RGB in
    [0, 1] in time order; ``lidar_points``: each image's camera-frame returns ``(M, 3)``;
    ``poses_world_cam`` ``(K, 4, 4)``), 0 where it cannot be measured."""
    greys = [grey(image) for image in images]
    ratios = np.zeros(max(len(images) - 1, 0))
    for i in range(len(ratios)):
        gain = log_gain(
            greys[i], greys[i + 1], lidar_points[i], camera, poses_world_cam[i], poses_world_cam[i + 1]
        )
        ratios[i] = 0.0 if gain is None else gain
    return ratios


#: Fewer shared LiDAR points than this say nothing about two images' gains.
MIN_SHARED_POINTS = 50
#: A pair's gain counts when at least this fraction of its shared points agree with the median
#: log ratio to within :data:`GAIN_AGREEMENT` (without it, on a 2-minute corridor with pillars the
#: few pairs taken across a bend chained to a 64 % spread in images of one gain).
MIN_AGREEING_FRACTION = 0.5
GAIN_AGREEMENT = 0.05
#: With ``exposure: auto``, the maps are learnt when the images' gains, chained from one image to
#: the next, span more than this (log ratio: 5 %).
GAIN_SPREAD_LIMIT = math.log(1.05)


def gain_spread(log_ratios: np.ndarray) -> float:
    """How far the gains chained from the neighbouring images' log ratios ``(K - 1,)`` spread (the
    range of their running sum, the first image at 0)."""
    return float(np.ptp(np.concatenate([[0.0], np.cumsum(log_ratios)])))


def _sampled(grey: np.ndarray, points: np.ndarray, camera, T_world_cam: np.ndarray) -> np.ndarray:
    """``(M,)`` grey level of ``grey`` ``(H, W)`` at the pixels of world points ``(M, 3)`` seen by
    ``camera`` at ``T_world_cam`` (NaN outside its image or behind it)."""
    values = np.full(len(points), np.nan)
    index, rows, cols, _ = in_view(points, camera, T_world_cam)
    values[index] = grey[rows, cols]
    return values
