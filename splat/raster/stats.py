"""Per-triangle geometric error statistics over the pixels each triangle dominates (for
geometric-variance densification)."""

from __future__ import annotations

from dataclasses import dataclass

import torch
from torch import Tensor


@dataclass
class ErrorStats:
    """Count, sum and sum of squares ``(F,)`` of an error over the pixels a face dominates."""

    count: Tensor
    sum: Tensor
    sum_sq: Tensor

    def variance(self) -> Tensor:
        """``(F,)`` population variance ``E[e^2] - E[e]^2`` (0 where the count is 0)."""
        n = self.count.clamp(min=1).to(self.sum.dtype)
        return (self.sum_sq / n - (self.sum / n) ** 2).clamp(min=0)


def _accumulate(dominant: Tensor, error: Tensor, valid: Tensor, n_faces: int) -> ErrorStats:
    owned = valid & (dominant >= 0)
    ids, e = dominant[owned], error[owned]
    # bincount sums serially on the CPU, so the statistics are deterministic there.
    return ErrorStats(
        count=torch.bincount(ids, minlength=n_faces),
        sum=torch.bincount(ids, weights=e, minlength=n_faces).to(error.dtype),
        sum_sq=torch.bincount(ids, weights=e * e, minlength=n_faces).to(error.dtype),
    )


@torch.no_grad()
def depth_error_stats(dominant: Tensor, depth: Tensor, target: Tensor, n_faces: int) -> ErrorStats:
    """Stats of ``target - depth`` (both ``(H, W)``); pixels whose target is not > 0 are skipped.

    ``dominant`` is ``(H, W)`` int64 face index (-1 for none).
    """
    valid = torch.isfinite(target) & (target > 0)
    return _accumulate(dominant, torch.where(valid, target - depth, 0.0), valid, n_faces)


@torch.no_grad()
def normal_error_stats(dominant: Tensor, normal: Tensor, target: Tensor, n_faces: int) -> ErrorStats:
    """Stats of ``1 - n_gt . n_r`` with ``n_r`` the unit rendered normal, both ``(H, W, 3)``;
    pixels whose target is zero or not finite are skipped."""
    length = normal.norm(dim=-1, keepdim=True)
    unit = normal / length.clamp(min=torch.finfo(normal.dtype).tiny)
    valid = torch.isfinite(target).all(dim=-1) & (target.abs().sum(dim=-1) > 0) & (length[..., 0] > 0)
    error = 1.0 - (torch.where(valid[..., None], target, 0.0) * unit).sum(dim=-1)
    return _accumulate(dominant, error, valid, n_faces)
