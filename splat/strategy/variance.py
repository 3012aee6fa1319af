"""Geometric-variance densification (ours).

Over the pixels a triangle dominates, the variance of the depth error σd² (LiDAR depth minus the
rendered accumulated depth ``Σ w z``) and of the normal error σn² (``1 - n_prior · n_rendered``)
(Eq. 4–7), *normalised by their noise floors*: ``rd = σd² / lidar_noise_m²`` and
``rn = σn² / normal_noise²``. Triangles with both below 1 are within sensor noise and never sampled;
the others are sampled with probability ∝ ``max(rd, rn)``. A sampled triangle's depth variance
**dominates** when ``rd ≥ rn``: it is cloned (a depth discontinuity needs a second, free-moving
triangle); otherwise it is subdivided at its edge midpoints into 4 (curvature needs smaller facets).
"""

from __future__ import annotations

from collections.abc import Callable

import torch
from torch import Tensor

from splat.config import TrainConfig
from splat.model import TriangleModel
from splat.raster import DominantSums, RenderOutput
from splat.raster.project import ALPHA_MIN
from splat.strategy.sampling import SamplingStrategy
from splat.views import View

#: Pixels a triangle must dominate before its variance means anything.
MIN_PIXELS = 4


def depth_error(out: RenderOutput, lidar_depth: Tensor) -> tuple[Tensor, Tensor]:
    """Per-pixel ``lidar_depth - accumulated depth`` ``(H, W)`` and where it counts ``(H, W)`` bool
    (a finite LiDAR return > 0)."""
    valid = torch.isfinite(lidar_depth) & (lidar_depth > 0)
    return lidar_depth - out.accumulated_depth.detach(), valid


def normal_error(out: RenderOutput, prior: Tensor) -> tuple[Tensor, Tensor]:
    """Per-pixel ``1 - n_prior · n_r`` ``(H, W)`` with ``n_r`` the unit rendered normal, and where it
    counts ``(H, W)`` bool (a finite, non-zero prior and a rendered normal)."""
    normal = out.normal.detach()
    length = normal.norm(dim=-1, keepdim=True)
    unit = normal / length.clamp(min=torch.finfo(normal.dtype).tiny)
    valid = torch.isfinite(prior).all(dim=-1) & (prior.abs().sum(dim=-1) > 0) & (length[..., 0] > 0)
    return 1.0 - (prior * unit).sum(dim=-1), valid


class VarianceStrategy(SamplingStrategy):
    """Samples triangles whose depth or normal error varies beyond sensor noise (module docstring)."""

    def __init__(self, config: TrainConfig, log: Callable[[str], None]):
        super().__init__(config, log)
        self.depth_error = DominantSums.zeros(0, torch.float32, torch.device("cpu"))
        self.normal_error = DominantSums.zeros(0, torch.float32, torch.device("cpu"))

    def initialize(self, model: TriangleModel) -> None:
        """Zero the seen-statistics and the depth and normal error sums ``(F,)``."""
        super().initialize(model)
        dtype, n = model.params["vertices"].dtype, model.n_triangles
        self.depth_error = DominantSums.zeros(n, dtype, model.device)
        self.normal_error = DominantSums.zeros(n, dtype, model.device)

    def gather(self, model: TriangleModel, out: RenderOutput, view: View) -> None:
        """Fold in ``out``'s blending weights and its depth/normal errors against ``view``'s LiDAR
        depth and normal prior (where the view has them)."""
        super().gather(model, out, view)
        if view.depth is not None:
            self.depth_error.add(out.dominant_sums(*depth_error(out, view.depth)))
        if view.normal is not None:
            self.normal_error.add(out.dominant_sums(*normal_error(out, view.normal)))

    def _noise_ratios(self) -> tuple[Tensor, Tensor]:
        """``rd``, ``rn`` ``(F,)``: error variances over their noise floors (0 below MIN_PIXELS)."""
        rd = self.depth_error.variance() / self.config.lidar_noise_m**2
        rn = self.normal_error.variance() / self.config.normal_noise**2
        rd = torch.where(self.depth_error.count >= MIN_PIXELS, rd, 0.0)
        rn = torch.where(self.normal_error.count >= MIN_PIXELS, rn, 0.0)
        return rd, rn

    def sampling_weights(self, model: TriangleModel) -> tuple[Tensor, Tensor]:
        """``max(rd, rn)`` for seen triangles above the noise floor, else 0 ``(F,)``; clone where
        ``rd ≥ rn`` ``(F,)`` bool."""
        seen = self.max_weight.to(model.device) >= ALPHA_MIN
        rd, rn = self._noise_ratios()
        above_noise = (rd > 1) | (rn > 1)
        return torch.where(above_noise & seen, torch.maximum(rd, rn), 0.0), rd >= rn

    def below_noise_floor(self, weights: Tensor) -> int:
        return int(((weights == 0) & (self.max_weight.to(weights.device) > 0)).sum())

    def state_dict(self) -> dict:
        return {**super().state_dict(), "depth_error": self.depth_error, "normal_error": self.normal_error}

    def load_state_dict(self, state: dict) -> None:
        super().load_state_dict(state)
        self.depth_error, self.normal_error = state["depth_error"], state["normal_error"]
