"""Merge the blocks' trained models into one model, as if one run had trained the whole scene.

Each block keeps the triangles whose centroid lies in its core grown by half its typical triangle
(:func:`seam_overlap`): a triangle is independent of its neighbours, and one that straddles the
seam has its centroid on one side in one block and on the other side in the next, so the plain
core test would leave a gap of up to half a triangle along every seam. The few duplicates the
overlap keeps are opaque surfaces drawn twice; the collision mesh's export welds and deduplicates
them. The background (harmonics and map of the sky) and the sphere it lies on are the blocks'
averages weighted by their training keyframes (each block's sphere lies about its own cameras: the
average is an approximation, as is averaging what each block saw of the sky).
"""

from __future__ import annotations

import numpy as np
import torch
from torch import Tensor

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
    background = _weighted_mean([m.background for m in models], weights)
    if background is not None:
        background = background.requires_grad_(True)
    sphere = _weighted_mean([m.background_sphere for m in models], weights)
    last = models[0]
    return TriangleModel(params, last.sigma, last.opacity_floor, background, sphere)


def _weighted_mean(tensors: list[Tensor | None], weights: list[float]) -> Tensor | None:
    """The ``weights``' mean of those of ``tensors`` (one shape) that are not None (None if all are)."""
    present = [(t.detach(), w) for t, w in zip(tensors, weights, strict=True) if t is not None]
    if not present:
        return None
    total = sum(w for _, w in present)
    return sum(t * (w / total) for t, w in present).clone()
