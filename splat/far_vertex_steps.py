"""Vertex steps that grow with the distance from the cameras, so that far geometry can move.

Adam moves every vertex by about ``lr_vertices`` metres a step, whatever its distance. Near the
cameras that is a fraction of a pixel; far away it is far less, and camera-only triangles 20-60 m
away, which start several metres from their surface (rooflines and far facades of a street stand
a median 17 % too near), can hardly move in a run: the model did not fit its own training views at
the skyline (14 dB on the sky pixels beside it, docs/outdoor.md). Beyond ``range_m`` from the
nearest training camera a camera-only triangle's step is scaled by its distance over ``range_m``:
the same step seen from the cameras, in angle, as at ``range_m``. Triangles a LiDAR return backs
start on their surface and keep their steps (scaled too, they drifted from the LiDAR: on the 8 s
street the LiDAR agreement fell from 0.956 to 0.950 and twice as much of the mesh lay in the
vehicles' swept volumes). Nearer triangles (a room) are unchanged.
"""

from __future__ import annotations

from collections.abc import Callable

import torch
from torch import Tensor


def distance_scale(triangles: Tensor, camera_centres: Tensor, range_m: float) -> Tensor:
    """``(F,)``: each triangle's (``triangles`` ``(F, 3, 3)``) distance from the nearest of
    ``camera_centres`` ``(V, 3)`` over ``range_m``, at least 1."""
    distance = torch.cdist(triangles.mean(dim=1), camera_centres.to(triangles)).amin(dim=1)
    return (distance / range_m).clamp(min=1.0)


class FarVertexSteps:
    """Scales each optimiser step of the model's ``vertices`` per camera-only triangle (those
    ``camera_only`` ``(F, 3, 3) -> (F,)`` bool flags) by :func:`distance_scale` (module
    docstring). The triangles so scaled and their scales are kept while the parameter tensor stays
    the same one: they are found anew when densification or pruning replaces it (vertices move
    little between), and go into checkpoints (:meth:`state_dict`) so that a resumed run continues
    bit for bit. The others' steps are left exactly as the optimiser made them."""

    def __init__(
        self, camera_centres: Tensor, range_m: float, camera_only: Callable[[Tensor], Tensor]
    ) -> None:
        self.camera_centres, self.range_m, self.camera_only = camera_centres, range_m, camera_only
        self._for: Tensor | None = None
        self._far = torch.zeros(0, dtype=torch.long)
        self._scale = torch.zeros(0)

    @torch.no_grad()
    def step(self, vertices: Tensor, optimizer_step: Callable[[], object]) -> None:
        """Run ``optimizer_step()`` (which updates ``vertices`` ``(F, 3, 3)`` in place) and scale
        the move it made of each far camera-only triangle's vertices."""
        if self._for is not vertices:
            scale = distance_scale(vertices, self.camera_centres, self.range_m)
            far = (scale > 1) & self.camera_only(vertices).to(scale.device)
            self._far = torch.nonzero(far).squeeze(1)
            self._scale, self._for = scale[self._far, None, None], vertices
        before = vertices[self._far]
        optimizer_step()
        vertices[self._far] = before + self._scale * (vertices[self._far] - before)

    def state_dict(self) -> dict[str, Tensor] | None:
        """The far triangles' rows and scales in use, or None before the first step."""
        return None if self._for is None else {"far": self._far.clone(), "scale": self._scale.clone()}

    def load_state_dict(self, state: dict[str, Tensor] | None, vertices: Tensor) -> None:
        """Use ``state`` (:meth:`state_dict`) for the model's restored ``vertices``."""
        if state is not None:
            self._far, self._scale, self._for = state["far"], state["scale"].to(vertices), vertices
