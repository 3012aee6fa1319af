"""Densification by sampling: every ``densify_every`` iterations until ``densify_until``, prune,
then clone or subdivide triangles drawn at random in proportion to a strategy's weights.

One step, from the statistics gathered since the last one:

1. **prune** triangles whose opacity fell below ``prune_opacity`` (but those on the far floor,
   :meth:`~splat.strategy.base.Strategy.keep_far_floor`) and, with ``prune_unseen``,
   triangles never seen (no blending weight ≥ 1/255 in any rendered view);
2. **sample** candidates without replacement in proportion to the strategy's weights, with a
   budget of ``growth_rate × F`` new triangles (capped by ``max_triangles``): a clone costs one new
   triangle, a subdivision three;
3. **grow**: replace each sampled triangle by its two clones or its four midpoint children
   (``clone``/``subdivide`` switch either off); when no triangle has a positive weight the step is
   skipped and reported (never a crash).
"""

from __future__ import annotations

from collections.abc import Callable

import torch
from torch import Tensor

from splat.config import TrainConfig
from splat.model import TriangleModel
from splat.param_rows import replace_rows
from splat.raster import RenderOutput
from splat.raster.project import ALPHA_MIN
from splat.strategy.base import DensifyReport, Strategy
from splat.strategy.growth import cloned_rows, subdivided_rows
from splat.views import View


class SamplingStrategy(Strategy):
    """The schedule, seen-statistics and prune/sample/grow step shared by the sampling strategies;
    a subclass gives the weights (:meth:`sampling_weights`) and any statistics they need."""

    def __init__(self, config: TrainConfig, log: Callable[[str], None]):
        super().__init__(config, log)
        self.generator = torch.Generator().manual_seed(config.seed)
        self.max_weight = torch.zeros(0)

    def initialize(self, model: TriangleModel) -> None:
        """Zero the largest blending weight ``(F,)`` (CPU) seen of each triangle."""
        self.max_weight = torch.zeros(model.n_triangles, dtype=model.params["vertices"].dtype)

    def last_densification(self) -> int:
        """How many iterations are done when the model is densified for the last time (0: never)."""
        c = self.config
        return int(c.densify_until * c.iterations) // c.densify_every * c.densify_every

    def collects_at(self, iteration: int) -> bool:
        """Whether ``iteration``'s render feeds the statistics: only the renders before the last
        densification (on the default preset, 1500 of 3000 iterations, not the 1650 up to
        ``densify_until``)."""
        return iteration < self.last_densification()

    def densifies_after(self, iteration: int) -> bool:
        """Whether the model is densified after ``iteration`` (0-based)."""
        done = iteration + 1
        return done % self.config.densify_every == 0 and done <= self.last_densification()

    def gather(self, model: TriangleModel, out: RenderOutput, view: View) -> None:
        """Fold one render of ``view`` into the statistics."""
        torch.maximum(self.max_weight, out.max_weight.detach().cpu(), out=self.max_weight)

    def sampling_weights(self, model: TriangleModel) -> tuple[Tensor, Tensor]:
        """Sampling weight ``(F,)`` (0 = never sampled) and whether cloning is preferred ``(F,)`` bool."""
        raise NotImplementedError

    def below_noise_floor(self, weights: Tensor) -> int:
        """How many seen triangles the weights leave out as within sensor noise (reported)."""
        return 0

    def after_step(
        self,
        model: TriangleModel,
        optimizer: torch.optim.Optimizer,
        iteration: int,
        out: RenderOutput | None,
        view: View,
    ) -> DensifyReport | None:
        """Gather ``out``'s statistics while collecting; densify on schedule."""
        if out is not None and self.collects_at(iteration):
            self.gather(model, out, view)
        if not self.densifies_after(iteration):
            return None
        report = self.densify(model, optimizer, iteration + 1)
        self.log(
            f"densify @{report.iteration}: pruned {report.pruned}, cloned {report.cloned}, "
            f"subdivided {report.subdivided} → {report.after} triangles"
        )
        return report

    def densify(
        self, model: TriangleModel, optimizer: torch.optim.Optimizer, iteration: int
    ) -> DensifyReport:
        """One prune/sample/grow step now (see the module docstring), labelled ``iteration``; the
        optimiser's state follows the rows and the statistics start again."""
        c = self.config
        report = DensifyReport(iteration, model.n_triangles)
        weights, prefer_clone = self.sampling_weights(model)
        report.below_noise_floor = self.below_noise_floor(weights)
        seen = self.max_weight.to(model.device) >= ALPHA_MIN
        # An unseen triangle keeps its opacity, so only seen ones can fall below the threshold.
        keep = self.opaque_or_far_floor(model, c.prune_opacity)
        if c.prune_unseen:
            keep &= seen
        if not bool(keep.any()):
            keep = torch.ones_like(keep)  # pruning everything would end the run with an empty model
            report.extra["prune_skipped"] = "every triangle was prunable (none seen since the last step)"
        report.pruned = int((~keep).sum())
        weights = torch.where(keep, weights, 0.0)
        if not c.clone:
            prefer_clone = torch.zeros_like(prefer_clone)
        if not c.subdivide:
            prefer_clone = torch.ones_like(prefer_clone)

        chosen = self._sample(weights, prefer_clone, int(keep.sum()), report)
        clone_rows = chosen[prefer_clone[chosen]]
        split_rows = chosen[~prefer_clone[chosen]]
        report.cloned, report.subdivided = len(clone_rows), len(split_rows)

        remove = ~keep
        remove[chosen] = True  # replaced by its two copies or its four children
        added = [cloned_rows(model, clone_rows), subdivided_rows(model, split_rows)]
        replace_rows(model, optimizer, ~remove, {k: torch.cat([a[k] for a in added]) for k in model.params})
        report.after = model.n_triangles
        self.initialize(model)
        return report

    def _sample(self, weights: Tensor, prefer_clone: Tensor, kept: int, report: DensifyReport) -> Tensor:
        """Rows ``(K,)`` drawn without replacement ∝ ``weights`` within the budget of new triangles;
        records in ``report`` why none were drawn."""
        c = self.config
        budget = min(int(c.growth_rate * kept), c.max_triangles - kept)
        candidates = int((weights > 0).sum())
        if budget <= 0:
            report.skipped = f"triangle budget reached ({c.max_triangles})"
        elif candidates == 0:
            report.skipped = "no triangle has a positive sampling weight (all within noise or unseen)"
        else:
            order = torch.multinomial(
                weights.cpu(), min(budget, candidates), replacement=False, generator=self.generator
            ).to(weights.device)
            cost = torch.where(prefer_clone[order], 1, 3)
            return order[torch.cumsum(cost, 0) <= budget]
        return torch.zeros(0, dtype=torch.int64, device=weights.device)

    def state_dict(self) -> dict:
        return {
            **super().state_dict(),
            "generator": self.generator.get_state(),
            "max_weight": self.max_weight,
        }

    def load_state_dict(self, state: dict) -> None:
        super().load_state_dict(state)
        self.generator.set_state(state["generator"])
        self.max_weight = state["max_weight"]
