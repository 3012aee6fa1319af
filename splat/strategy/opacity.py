"""Opacity densification (the TS+ baseline): seen triangles are sampled with probability ∝ their
opacity and subdivided."""

from __future__ import annotations

import torch
from torch import Tensor

from splat.model import TriangleModel
from splat.raster.project import ALPHA_MIN
from splat.strategy.sampling import SamplingStrategy


class OpacityStrategy(SamplingStrategy):
    """TS+ opacity sampling; its only statistic is whether a triangle was seen."""

    def sampling_weights(self, model: TriangleModel) -> tuple[Tensor, Tensor]:
        """The opacity of seen triangles, else 0 ``(F,)``; never prefers cloning ``(F,)`` bool."""
        seen = self.max_weight.to(model.device) >= ALPHA_MIN
        return torch.where(seen, model.triangle_opacity().detach(), 0.0), torch.zeros_like(seen)
