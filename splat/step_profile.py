"""Where a training iteration's time goes: a :class:`~splat.trainer.Trainer` that times each part.

:class:`ProfiledTrainer` runs the same iterations as the trainer (same views, schedule,
densification and optimiser steps) but splits each one into timed sections. The render's outputs
are detached into leaves, so the loss's backward pass (down to the images) and the rasteriser's
backward pass (from the images to the triangles) are timed apart; the gradients reach the
parameters as in a plain step. D-SSIM is timed once more on its own (forward and backward, not
counted in the total) to say how much of the loss it is. Evaluations of the held-out views are
timed per call and spread over the iterations between them.
"""

from __future__ import annotations

import time
from collections import defaultdict
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import replace
from typing import Any

import torch

from splat.losses import dssim, training_loss
from splat.trainer import Trainer, _apply_schedule

#: The render outputs the loss reads; gradients come back to the rasteriser through them.
LOSS_INPUTS = ("rgb", "accumulated_depth", "alpha", "normal", "distortion")
#: Sections in the order of a step (their sum is the step's time).
SECTIONS = (
    "strategy before step",
    "render forward",
    "loss forward",
    "loss backward",
    "raster backward",
    "optimizer step",
    "strategy after step (densification statistics)",
    "evaluation (held-out views)",
)
#: D-SSIM once more on its own, outside the sum: how much of the two loss sections it is.
DSSIM_SHARE = "D-SSIM forward+backward (part of loss)"


class ProfiledTrainer(Trainer):
    """A :class:`Trainer` whose steps are timed by section (:meth:`profile`)."""

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        super().__init__(*args, **kwargs)
        self._seconds: dict[str, float] = defaultdict(float)
        self._steps = 0

    @contextmanager
    def _timed(self, section: str) -> Iterator[None]:
        cuda = self.config.device.startswith("cuda")
        if cuda:
            torch.cuda.synchronize()
        started = time.perf_counter()
        yield
        if cuda:
            torch.cuda.synchronize()
        self._seconds[section] += time.perf_counter() - started

    def _step(self, it: int) -> dict[str, float] | None:
        self._steps += 1
        with self._timed(SECTIONS[0]):
            self.strategy.before_step(self.model, self.optimizer, it)
            # The schedule only sets a few numbers; it is counted with the strategy's work.
            _apply_schedule(self.model, self.optimizer, self.config, it)
            index, view, camera = self._training_view(it)
        with self._timed(SECTIONS[1]):
            out, priors = self._render_training_view(index, view, camera)
            opacity = self.model.triangle_opacity()
        leaves = {name: getattr(out, name).detach().requires_grad_() for name in LOSS_INPUTS}
        with self._timed(SECTIONS[2]):
            terms = training_loss(
                replace(out, **leaves), view.image, view.depth, view.normal, opacity, self.config,
                moving_mask=view.moving_mask, target_moments=view.image_moments, **priors,
            )  # fmt: skip
        with self._timed(SECTIONS[3]):
            terms.total.backward()
        with self._timed(SECTIONS[4]):
            pairs = [(getattr(out, n), leaf.grad) for n, leaf in leaves.items() if leaf.grad is not None]
            if pairs:
                torch.autograd.backward([p[0] for p in pairs], [p[1] for p in pairs])
        if self.config.lambda_dssim > 0:
            with self._timed(DSSIM_SHARE):
                rgb = out.rgb.detach().requires_grad_()
                dssim(rgb, view.image, target_moments=view.image_moments).backward()
        with self._timed(SECTIONS[5]):
            accepted = self._optimizer_step(terms.total, it)
        with self._timed(SECTIONS[6]):
            report = self.strategy.after_step(self.model, self.optimizer, it, out if accepted else None, view)
            self._record(report)
        return terms.as_floats() if accepted else None

    def _evaluate(self, it: int, losses: dict[str, float]) -> None:
        with self._timed(SECTIONS[7]):
            super()._evaluate(it, losses)

    def profile(self) -> dict[str, Any]:
        """Milliseconds per iteration of each section (and the share of the D-SSIM term), their
        total, and the iteration count they are averaged over."""
        steps = max(self._steps, 1)
        per_iteration = {s: round(self._seconds[s] * 1e3 / steps, 3) for s in SECTIONS}
        total = sum(per_iteration.values())
        return {
            "iterations": self._steps,
            "ms_per_iteration": per_iteration,
            "ms_total": round(total, 3),
            "dssim_ms": round(self._seconds[DSSIM_SHARE] * 1e3 / steps, 3),
            "n_triangles_end": self.model.n_triangles,
        }
