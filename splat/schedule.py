"""Training schedules (TS+): sigma annealing, the rising opacity floor, learning-rate decay."""

from __future__ import annotations

import math
from dataclasses import dataclass

from splat.config import TrainConfig


def _ramp(progress: float, start: float, end: float) -> float:
    """0 before ``start``, 1 after ``end``, linear in between."""
    if progress <= start:
        return 0.0
    if progress >= end or end <= start:
        return 1.0
    return (progress - start) / (end - start)


@dataclass(frozen=True)
class ScheduleState:
    """Schedule values at one iteration."""

    sigma: float
    opacity_floor: float
    lr_factor: float
    vertex_lr_factor: float


def schedule_at(config: TrainConfig, iteration: int) -> ScheduleState:
    """Schedule values at ``iteration`` (0-based) of ``config.iterations``.

    - sigma: log-linear from ``sigma_start`` to ``sigma_end`` until ``sigma_anneal_end``;
    - opacity floor: 0, rising linearly to 1 between ``floor_rise_start`` and ``floor_rise_end``;
    - learning rates: exponential decay to ``lr_final_factor``; vertices frozen (factor 0) for the
      first ``vertex_lr_delay`` so that colours settle before geometry moves.
    """
    p = iteration / max(config.iterations, 1)
    a = _ramp(p, 0.0, config.sigma_anneal_end)
    sigma = math.exp((1 - a) * math.log(config.sigma_start) + a * math.log(config.sigma_end))
    floor = _ramp(p, config.floor_rise_start, config.floor_rise_end)
    lr_factor = config.lr_final_factor**p
    vertex_factor = 0.0 if p < config.vertex_lr_delay else lr_factor
    return ScheduleState(sigma, floor, lr_factor, vertex_factor)


def final_phase_start(config: TrainConfig) -> int:
    """First iteration at which every schedule has reached its final value (opaque, sharp): from
    here on, early stopping may end the run without leaving it half-annealed."""
    return math.ceil(max(config.sigma_anneal_end, config.floor_rise_end) * config.iterations)


def evaluation_due(config: TrainConfig, done: int) -> bool:
    """Whether the held-out views are evaluated after ``done`` iterations: every ``eval_every``,
    every ``final_eval_every`` from :func:`final_phase_start` on (where early stopping may end the
    run), and after the last."""
    if done == config.iterations or done % config.eval_every == 0:
        return True
    return done >= final_phase_start(config) and done % config.final_eval_every == 0
