"""Densification strategies: objects that own their statistics, schedule, final prune and row
surgery, driven by the trainer through two hooks (:class:`Strategy`'s ``before_step`` and
``after_step``), as gsplat's strategies are.

``config.densify`` picks one: ``variance`` (ours, :class:`VarianceStrategy`), ``opacity`` (TS+,
:class:`OpacityStrategy`) or ``none`` (only the final prune, :class:`Strategy`).
"""

from __future__ import annotations

from collections.abc import Callable

from splat.config import TrainConfig
from splat.strategy.base import DensifyReport, Strategy
from splat.strategy.opacity import OpacityStrategy
from splat.strategy.sampling import SamplingStrategy
from splat.strategy.variance import VarianceStrategy

STRATEGIES: dict[str, type[Strategy]] = {
    "variance": VarianceStrategy,
    "opacity": OpacityStrategy,
    "none": Strategy,
}


def strategy_for(config: TrainConfig, log: Callable[[str], None]) -> Strategy:
    """The strategy ``config.densify`` names, logging through ``log``."""
    return STRATEGIES[config.densify](config, log)


__all__ = [
    "STRATEGIES",
    "DensifyReport",
    "OpacityStrategy",
    "SamplingStrategy",
    "Strategy",
    "VarianceStrategy",
    "strategy_for",
]
