"""Densification: geometric-variance sampling (ours) and the TS+ opacity sampling (baseline).

Every ``densify_every`` iterations, from the per-triangle statistics accumulated since the last
densification (:class:`DensifyStats`):

1. **prune** triangles whose opacity fell below ``prune_opacity`` and, with ``prune_unseen``,
   triangles never seen (no blending weight ≥ 1/255 in any rendered view);
2. **sample** candidates without replacement, with a budget of ``growth_rate × F`` new triangles
   (capped by ``max_triangles``):

   - ``variance`` (ours): the depth-error variance σd² and normal-error variance σn² over the
     pixels a triangle dominates (Eq. 4–7), *normalised by their noise floors*:
     ``rd = σd² / lidar_noise_m²`` and ``rn = σn² / normal_noise²``. Triangles with both below 1
     are within sensor noise and never sampled; the others are sampled with probability ∝
     ``max(rd, rn)``. A sampled triangle's depth variance **dominates** when ``rd ≥ rn``: it is
     cloned (a depth discontinuity needs a second, free-moving triangle); otherwise it is
     subdivided at its edge midpoints into 4 (curvature needs smaller facets);
   - ``opacity`` (TS+): probability ∝ opacity among seen triangles, subdivision only.

3. when no triangle has a positive weight the step is skipped and logged (never a crash).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import torch
from torch import Tensor

from splat.config import TrainConfig
from splat.model import LOGIT_LIMIT, TriangleModel, logit
from splat.param_rows import replace_rows
from splat.raster import ErrorStats, RenderOutput
from splat.raster.project import ALPHA_MIN

#: Pixels a triangle must dominate before its variance means anything.
MIN_PIXELS = 4


def _zero_stats(n: int, dtype: torch.dtype, device: torch.device) -> ErrorStats:
    z = torch.zeros(n, dtype=dtype, device=device)
    return ErrorStats(torch.zeros(n, dtype=torch.int64, device=device), z.clone(), z.clone())


def _add(total: ErrorStats, new: ErrorStats | None) -> None:
    if new is not None:
        total.count += new.count
        total.sum += new.sum
        total.sum_sq += new.sum_sq


@dataclass
class DensifyStats:
    """Per-triangle statistics ``(F,)`` accumulated over the renders since the last densification."""

    depth: ErrorStats
    normal: ErrorStats
    max_weight: Tensor

    @classmethod
    def empty(cls, n: int, dtype: torch.dtype, device: torch.device) -> DensifyStats:
        return cls(_zero_stats(n, dtype, device), _zero_stats(n, dtype, device), torch.zeros(n, dtype=dtype))

    def add(self, out: RenderOutput) -> None:
        """Fold in one render's statistics."""
        _add(self.depth, out.depth_error)
        _add(self.normal, out.normal_error)
        torch.maximum(self.max_weight, out.max_weight.detach().cpu(), out=self.max_weight)


@dataclass
class DensifyReport:
    """What one densification step did."""

    iteration: int
    before: int
    pruned: int = 0
    cloned: int = 0
    subdivided: int = 0
    after: int = 0
    below_noise_floor: int = 0
    skipped: str | None = None
    extra: dict = field(default_factory=dict)


def sampling_weights(model: TriangleModel, stats: DensifyStats, config: TrainConfig) -> tuple[Tensor, Tensor]:
    """Sampling weight ``(F,)`` (0 = never sampled) and whether cloning is preferred ``(F,)`` bool."""
    seen = stats.max_weight.to(model.device) >= ALPHA_MIN
    if config.densify == "opacity":
        weights = torch.where(seen, model.triangle_opacity().detach(), 0.0)
        return weights, torch.zeros_like(seen)
    rd = stats.depth.variance() / config.lidar_noise_m**2
    rn = stats.normal.variance() / config.normal_noise**2
    rd = torch.where(stats.depth.count >= MIN_PIXELS, rd, 0.0)
    rn = torch.where(stats.normal.count >= MIN_PIXELS, rn, 0.0)
    above_noise = (rd > 1) | (rn > 1)
    weights = torch.where(above_noise & seen, torch.maximum(rd, rn), 0.0)
    return weights, rd >= rn


def _cloned(model: TriangleModel, rows: Tensor) -> dict[str, Tensor]:
    """Two copies of each of ``rows`` (``2K`` rows), each with opacity ``1 - sqrt(1 - o)`` so that
    together they let through what the original did."""
    p = model.params
    o = torch.sigmoid(p["opacity"].detach()[rows])
    return {
        "vertices": p["vertices"].detach()[rows].repeat(2, 1, 1),
        "colors": p["colors"].detach()[rows].repeat(2, 1, 1),
        "opacity": logit(1 - torch.sqrt(1 - o)).to(o).repeat(2),
    }


def _subdivided(model: TriangleModel, rows: Tensor) -> dict[str, Tensor]:
    """The 4 midpoint triangles of each of ``rows`` (``4K`` rows), colours interpolated."""
    v = model.params["vertices"].detach()[rows]
    c = model.triangle_colors().detach()[rows]

    def split(x: Tensor) -> Tensor:
        a, b, cc = x[:, 0], x[:, 1], x[:, 2]
        ab, bc, ca = (a + b) / 2, (b + cc) / 2, (cc + a) / 2
        return torch.cat([
            torch.stack([a, ab, ca], 1), torch.stack([ab, b, bc], 1),
            torch.stack([ca, bc, cc], 1), torch.stack([ab, bc, ca], 1),
        ])  # fmt: skip

    return {
        "vertices": split(v),
        "colors": logit(split(c)).to(c).clamp(-LOGIT_LIMIT, LOGIT_LIMIT),
        "opacity": model.params["opacity"].detach()[rows].repeat(4),
    }


def densify(
    model: TriangleModel,
    optimizer: torch.optim.Optimizer,
    stats: DensifyStats,
    config: TrainConfig,
    generator: torch.Generator,
    iteration: int,
) -> DensifyReport:
    """Prune, then clone/subdivide sampled triangles (see the module docstring); the optimiser's
    state follows the rows."""
    report = DensifyReport(iteration, model.n_triangles)
    weights, prefer_clone = sampling_weights(model, stats, config)
    if config.densify == "variance":
        report.below_noise_floor = int(((weights == 0) & (stats.max_weight.to(weights.device) > 0)).sum())
    seen = stats.max_weight.to(model.device) >= ALPHA_MIN
    # An unseen triangle keeps its opacity, so only seen ones can fall below the threshold.
    keep = model.triangle_opacity().detach() >= config.prune_opacity
    if config.prune_unseen:
        keep &= seen
    if not bool(keep.any()):
        keep = torch.ones_like(keep)  # pruning everything would end the run with an empty model
        report.extra["prune_skipped"] = "every triangle was prunable (none seen since the last step)"
    report.pruned = int((~keep).sum())
    weights = torch.where(keep, weights, 0.0)
    if not config.clone:
        prefer_clone = torch.zeros_like(prefer_clone)
    if not config.subdivide:
        prefer_clone = torch.ones_like(prefer_clone)

    budget = min(int(config.growth_rate * int(keep.sum())), config.max_triangles - int(keep.sum()))
    candidates = int((weights > 0).sum())
    chosen = torch.zeros(0, dtype=torch.int64, device=model.device)
    if budget <= 0:
        report.skipped = f"triangle budget reached ({config.max_triangles})"
    elif candidates == 0 or config.densify == "none":
        report.skipped = "no triangle has a positive sampling weight (all within noise or unseen)"
    else:
        order = torch.multinomial(
            weights.cpu(), min(budget, candidates), replacement=False, generator=generator
        )
        order = order.to(model.device)
        cost = torch.where(prefer_clone[order], 1, 3)
        chosen = order[torch.cumsum(cost, 0) <= budget]
    clone_rows = chosen[prefer_clone[chosen]]
    split_rows = chosen[~prefer_clone[chosen]]
    report.cloned, report.subdivided = len(clone_rows), len(split_rows)

    remove = ~keep
    remove[chosen] = True  # replaced by its two copies or its four children
    added = [_cloned(model, clone_rows), _subdivided(model, split_rows)]
    replace_rows(model, optimizer, ~remove, {k: torch.cat([a[k] for a in added]) for k in model.params})
    report.after = model.n_triangles
    return report
