"""The interface the trainer drives a densification strategy through, and the final prune every
strategy shares.

Each iteration the trainer calls :meth:`Strategy.before_step` (before it renders the iteration's
view) and :meth:`Strategy.after_step` (after the optimiser step, with the render). A strategy owns
its statistics, its schedule and its row surgery: whenever it adds or removes triangles it changes
the model's parameters and the optimiser's state together (:func:`splat.param_rows.replace_rows`).
Its :meth:`~Strategy.state_dict` goes into the training checkpoint, so a resumed run continues it
bit for bit.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np
import torch

from splat.config import TrainConfig
from splat.floor_cells import PlaneGrid, on_far_floor
from splat.model import TriangleModel
from splat.param_rows import replace_rows
from splat.raster import RenderOutput
from splat.views import View


@dataclass
class DensifyReport:
    """What one densification step did (an entry of ``summary.json``'s ``densification``)."""

    iteration: int
    before: int
    pruned: int = 0
    cloned: int = 0
    subdivided: int = 0
    after: int = 0
    below_noise_floor: int = 0
    skipped: str | None = None
    extra: dict = field(default_factory=dict)

    def note(self) -> str | None:
        """The line for the run's ``skips`` (work not done and why), if any."""
        if self.skipped:
            return f"densification at {self.iteration} skipped: {self.skipped}"
        if self.below_noise_floor:
            return (
                f"densification at {self.iteration}: {self.below_noise_floor} seen triangles within "
                "LiDAR/normal noise, not sampled"
            )
        return None


class Strategy:
    """No densification, only the final prune (``densify: none``); the base of the others.

    Final prune: once ``floor_rise_start`` is reached, before the opacity floor rises, triangles
    whose opacity is below ``final_prune_opacity`` are removed (the rising floor would otherwise
    turn them into opaque junk), but not those on the far floor (:meth:`keep_far_floor`).
    """

    def __init__(self, config: TrainConfig, log: Callable[[str], None]):
        self.config = config
        self.log = log
        self.final_pruned = False
        #: The scene's floor plane and the training cameras' centres ``(K, 3)`` (:meth:`keep_far_floor`).
        self.floor: PlaneGrid | None = None
        self.cameras = np.zeros((0, 3))

    def keep_far_floor(self, floor: PlaneGrid | None, cameras: np.ndarray) -> None:
        """Never prune the triangles lying on ``floor`` (the scene's floor plane) beyond
        :data:`~splat.floor_cells.NEAR_FLOOR_M` from every camera centre ``(K, 3)`` for their
        transparency, when the config's ``keep_far_floor`` says so."""
        self.floor = floor if self.config.keep_far_floor else None
        self.cameras = np.asarray(cameras, dtype=np.float64).reshape(-1, 3)

    def opaque_or_far_floor(self, model: TriangleModel, min_opacity: float) -> torch.Tensor:
        """``(F,)`` bool: the triangles a prune at ``min_opacity`` keeps: as opaque, or on the far floor."""
        keep = model.triangle_opacity().detach() >= min_opacity
        if self.floor is not None:
            triangles = model.params["vertices"].detach().cpu().double().numpy()
            keep |= torch.as_tensor(on_far_floor(self.floor, triangles, self.cameras), device=keep.device)
        return keep

    def initialize(self, model: TriangleModel) -> None:
        """Start fresh statistics for ``model``'s current rows (at the start, after any row change)."""

    def before_step(self, model: TriangleModel, optimizer: torch.optim.Optimizer, iteration: int) -> None:
        """Work before ``iteration``'s render: the final prune, once."""
        c = self.config
        if self.final_pruned or iteration < c.floor_rise_start * c.iterations:
            return
        self.final_pruned = True
        keep = self.opaque_or_far_floor(model, c.final_prune_opacity)
        if not bool(keep.all()):
            replace_rows(model, optimizer, keep, {k: v[:0].detach() for k, v in model.params.items()})
            self.initialize(model)
            self.log(f"pruned {int((~keep).sum())} transparent triangles before the opacity floor rises")

    def after_step(
        self,
        model: TriangleModel,
        optimizer: torch.optim.Optimizer,
        iteration: int,
        out: RenderOutput | None,
        view: View,
    ) -> DensifyReport | None:
        """Work after ``iteration``'s optimiser step; ``out`` is the render of ``view``, None when
        the step was rejected (non-finite). Returns a report when the model was densified."""
        return None

    def state_dict(self) -> dict:
        """Everything needed to continue this strategy bit for bit (plain values and tensors)."""
        return {"final_pruned": self.final_pruned}

    def load_state_dict(self, state: dict) -> None:
        """Inverse of :meth:`state_dict`."""
        self.final_pruned = state["final_pruned"]
