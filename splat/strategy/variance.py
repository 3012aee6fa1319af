"""Geometric-variance densification (ours).

Over the pixels a triangle dominates, the variance of the depth error σd² (LiDAR depth minus the
rendered accumulated depth ``Σ w z``) and of the normal error σn² (``1 - n_prior · n_rendered``)
(Eq. 4–7), *normalised by their noise floors*: ``rd = σd² / lidar_noise_m²`` and
``rn = σn² / normal_noise²``. Triangles with both below 1 are within sensor noise and never sampled;
the others are sampled with probability ∝ ``max(rd, rn)``. A sampled triangle's depth variance
**dominates** when ``rd ≥ rn``: it is cloned (a depth discontinuity needs a second, free-moving
triangle); otherwise it is subdivided at its edge midpoints into 4 (curvature needs smaller facets).

Where no LiDAR return backs a triangle (camera-only geometry above the LiDAR's field: facades,
crowns), neither variance exists and it would never grow finer than it started. There the variance
of the colour error σc² (image minus render, over the static pixels it dominates with alpha ≥ 1/2)
over its noise floor, ``rc = σc² / color_noise²``, takes their place: texture the triangle cannot
show; such triangles are subdivided. The two kinds share each step's budget in proportion to how
many of each are above their floor (:func:`shared_budget`).
"""

from __future__ import annotations

from collections.abc import Callable

import torch
from torch import Tensor

from splat.config import TrainConfig
from splat.model import TriangleModel
from splat.raster import DominantSums, RenderOutput
from splat.raster.extension import optional_cpu_extension
from splat.raster.project import ALPHA_MIN
from splat.strategy.sampling import SamplingStrategy
from splat.views import View

#: Pixels a triangle must dominate before its variance means anything.
MIN_PIXELS = 4


def lidar_returns(lidar_depth: Tensor) -> Tensor:
    """``(H, W)`` bool: the pixels of ``lidar_depth`` ``(H, W)`` with a finite LiDAR return > 0."""
    return torch.isfinite(lidar_depth) & (lidar_depth > 0)


def depth_error(out: RenderOutput, lidar_depth: Tensor) -> tuple[Tensor, Tensor]:
    """Per-pixel ``lidar_depth - accumulated depth`` ``(H, W)`` and where it counts ``(H, W)`` bool
    (:func:`lidar_returns`)."""
    return lidar_depth - out.accumulated_depth.detach(), lidar_returns(lidar_depth)


def normal_error(out: RenderOutput, prior: Tensor, known: Tensor) -> tuple[Tensor, Tensor]:
    """Per-pixel ``1 - n_prior · n_r`` ``(H, W)`` with ``n_r`` the unit rendered normal, and where it
    counts ``(H, W)`` bool: where the prior ``(H, W, 3)`` is ``known`` ``(H, W)`` bool (finite and
    non-zero, :attr:`~splat.views.View.normal_known`) and a normal is rendered."""
    normal = out.normal.detach()
    length = normal.norm(dim=-1, keepdim=True)
    unit = normal / length.clamp(min=torch.finfo(normal.dtype).tiny)
    return 1.0 - (prior * unit).sum(dim=-1), known & (length[..., 0] > 0)


def color_error(out: RenderOutput, view: View) -> tuple[Tensor, Tensor]:
    """Per-pixel mean over the channels of ``view.image - out.rgb`` ``(H, W)``, and where it counts
    ``(H, W)`` bool: no LiDAR return, no moving object, and the triangles mostly opaque (alpha ≥ 1/2;
    elsewhere the error is the background's)."""
    error = (view.image - out.rgb.detach()).mean(dim=-1)
    valid = out.alpha.detach() >= 0.5
    if view.depth is not None:
        valid &= ~lidar_returns(view.depth)
    if view.moving_mask is not None:
        valid &= ~view.moving_mask
    return error, valid


#: The depth, normal and colour error sums of one render (None: the view has no LiDAR depth, no
#: normal prior).
ErrorSums = tuple[DominantSums | None, DominantSums | None, DominantSums]


def error_sums(out: RenderOutput, view: View) -> ErrorSums:
    """The sums over the pixels each face dominates of :func:`depth_error`, :func:`normal_error`
    and :func:`color_error` of a render ``out`` of ``view``.

    On the CPU through the CPU extension (``csrc/error_sums_cpu.cpp``: one pass instead of a dozen,
    the same sums to the bit), elsewhere :func:`composed_error_sums`."""
    present = [t for t in (view.image, view.depth, view.normal) if t is not None]
    dtype = out.alpha.dtype
    fused = dtype in (torch.float32, torch.float64) and all(
        t.device.type == "cpu" and t.dtype == dtype for t in (out.alpha, *present)
    )
    kernel = optional_cpu_extension() if fused else None
    if kernel is None:
        return composed_error_sums(out, view)
    empty = out.alpha.new_empty(0)

    def given(t: Tensor | None, like: Tensor = empty) -> Tensor:
        return like if t is None else t.detach().contiguous()

    normal = given(out.normal)
    has_prior = view.normal is not None
    sums = kernel.error_sums(
        given(out.dominant), len(out.max_weight), given(out.accumulated_depth), given(view.depth),
        normal, normal.norm(dim=-1) if has_prior else empty,  # the length as normal_error's, to the bit
        given(view.normal), given(view.normal_known, empty.bool()), given(out.rgb), given(view.image),
        given(out.alpha), given(view.moving_mask, empty.bool()),
    )  # fmt: skip
    depth, normal_sums, color = (DominantSums(*sums[i : i + 3]) for i in (0, 3, 6))
    return (depth if view.depth is not None else None, normal_sums if has_prior else None, color)


def composed_error_sums(out: RenderOutput, view: View) -> ErrorSums:
    """:func:`error_sums` composed of PyTorch operations (its specification; the CUDA path)."""
    depth = None if view.depth is None else out.dominant_sums(*depth_error(out, view.depth))
    normal = None
    if view.normal is not None:
        normal = out.dominant_sums(*normal_error(out, view.normal, view.normal_known))
    return depth, normal, out.dominant_sums(*color_error(out, view))


def shared_budget(geometric: Tensor, photometric: Tensor) -> Tensor:
    """One sampling weight ``(F,)`` from two disjoint ones ``(F,)`` (0 = not a candidate), each
    scaled to sum to its number of candidates: a draw then picks either kind about as often as it
    has candidates. Unscaled, depth variances of thousands of times their floor at every LiDAR edge
    would take every draw from colour variances of tens. Either alone is returned as it is."""
    counts = [(w > 0).sum() for w in (geometric, photometric)]
    if min(counts) == 0:
        return geometric + photometric
    return sum(w * (n / w.sum()) for w, n in zip((geometric, photometric), counts, strict=True))


class VarianceStrategy(SamplingStrategy):
    """Samples triangles whose depth or normal error varies beyond sensor noise (module docstring)."""

    def __init__(self, config: TrainConfig, log: Callable[[str], None]):
        super().__init__(config, log)
        self.depth_error = DominantSums.zeros(0, torch.float32, torch.device("cpu"))
        self.normal_error = DominantSums.zeros(0, torch.float32, torch.device("cpu"))
        self.color_error = DominantSums.zeros(0, torch.float32, torch.device("cpu"))

    def initialize(self, model: TriangleModel) -> None:
        """Zero the seen-statistics and the depth, normal and colour error sums ``(F,)``."""
        super().initialize(model)
        dtype, n = model.params["vertices"].dtype, model.n_triangles
        self.depth_error = DominantSums.zeros(n, dtype, model.device)
        self.normal_error = DominantSums.zeros(n, dtype, model.device)
        self.color_error = DominantSums.zeros(n, dtype, model.device)

    def gather(self, model: TriangleModel, out: RenderOutput, view: View) -> None:
        """Fold in ``out``'s blending weights, its depth/normal errors against ``view``'s LiDAR
        depth and normal prior (where the view has them) and its colour error where the view has
        no LiDAR return."""
        super().gather(model, out, view)
        depth, normal, color = error_sums(out, view)
        if depth is not None:
            self.depth_error.add(depth)
        if normal is not None:
            self.normal_error.add(normal)
        self.color_error.add(color)

    def _noise_ratios(self) -> tuple[Tensor, Tensor, Tensor]:
        """``rd``, ``rn``, ``rc`` ``(F,)``: error variances over their noise floors (0 below
        MIN_PIXELS)."""
        ratios = []
        for sums, noise in ((self.depth_error, self.config.lidar_noise_m),
                            (self.normal_error, self.config.normal_noise),
                            (self.color_error, self.config.color_noise)):  # fmt: skip
            ratios.append(torch.where(sums.count >= MIN_PIXELS, sums.variance() / noise**2, 0.0))
        return ratios[0], ratios[1], ratios[2]

    def sampling_weights(self, model: TriangleModel) -> tuple[Tensor, Tensor]:
        """``max(rd, rn)`` for seen triangles above the noise floor, ``rc`` for those that no LiDAR
        return backs, else 0, shared as :func:`shared_budget` says ``(F,)``; clone where ``rd ≥ rn``
        and LiDAR backs the triangle ``(F,)`` bool."""
        seen = self.max_weight.to(model.device) >= ALPHA_MIN
        rd, rn, rc = self._noise_ratios()
        backed = (self.depth_error.count >= MIN_PIXELS) | (self.normal_error.count >= MIN_PIXELS)
        geometric = torch.where(((rd > 1) | (rn > 1)) & seen, torch.maximum(rd, rn), 0.0)
        photometric = torch.where((rc > 1) & seen & ~backed, rc, 0.0)
        return shared_budget(geometric, photometric), (rd >= rn) & backed

    def below_noise_floor(self, weights: Tensor) -> int:
        return int(((weights == 0) & (self.max_weight.to(weights.device) > 0)).sum())

    def state_dict(self) -> dict:
        return {**super().state_dict(), "depth_error": self.depth_error, "normal_error": self.normal_error,
                "color_error": self.color_error}  # fmt: skip

    def load_state_dict(self, state: dict) -> None:
        super().load_state_dict(state)
        self.depth_error, self.normal_error = state["depth_error"], state["normal_error"]
        # a checkpoint of an earlier release has no colour sums: they start again from zero
        zeros = DominantSums.zeros(
            len(self.depth_error.count), self.depth_error.sum.dtype, self.depth_error.sum.device
        )
        self.color_error = state.get("color_error", zeros)
