"""Merge the blocks' trained models into one model, as if one run had trained the whole scene.

Each block keeps the triangles whose centroid lies in its core grown by half its typical triangle
(:func:`seam_overlap`): a triangle is independent of its neighbours, and one that straddles the
seam has its centroid on one side in one block and on the other side in the next, so the plain
core test would leave a gap of up to half a triangle along every seam. The few duplicates the
overlap keeps are opaque surfaces drawn twice; the collision mesh's export welds and deduplicates
them. The background (harmonics and map of the sky, in world directions) is the blocks'
average weighted by their training keyframes.
"""

from __future__ import annotations

import numpy as np
import torch

from splat.blocks.partition import Block, GroundFrame
from splat.model import TriangleModel


def seam_overlap(model: TriangleModel) -> float:
    """Half the median longest edge of ``model``'s triangles (m): how far past its core a block
    keeps triangles."""
    v = model.params["vertices"].detach().cpu().double()
    if len(v) == 0:
        return 0.0
    edges = torch.linalg.norm(v - v.roll(1, dims=1), dim=2).max(dim=1).values
    return 0.5 * float(edges.median())


def core_triangles(model: TriangleModel, block: Block, frame: GroundFrame) -> np.ndarray:
    """``(F,)`` bool: ``model``'s triangles whose centroid lies in ``block``'s core grown by
    :func:`seam_overlap`."""
    centroids = model.params["vertices"].detach().mean(dim=1).cpu().double().numpy()
    return block.in_core(frame.project(centroids), seam_overlap(model))


def merge_models(models: list[TriangleModel], keep: list[np.ndarray], weights: list[float]) -> TriangleModel:
    """One model of the kept triangles of every block.

    Args:
        models: the blocks' trained models (same parameters, schedule state at its end).
        keep: ``(F_i,)`` bool per model: the triangles it contributes.
        weights: per model, its weight in the background's average (its training keyframes).
    """
    names = models[0].params.keys()
    params = {
        name: torch.cat(
            [m.params[name].detach()[torch.as_tensor(k)] for m, k in zip(models, keep, strict=True)]
        )
        .clone()
        .requires_grad_(True)
        for name in names
    }
    with_background = [(m.background.detach(), w) for m, w in zip(models, weights, strict=True)
                       if m.background is not None]  # fmt: skip
    background = None
    if with_background:
        total = sum(w for _, w in with_background)
        background = sum(b * (w / total) for b, w in with_background).clone().requires_grad_(True)
    last = models[0]
    return TriangleModel(params, last.sigma, last.opacity_floor, background)
