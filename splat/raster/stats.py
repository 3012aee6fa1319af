"""Per-triangle sums of a per-pixel quantity over the pixels each triangle dominates.

The rasteriser knows nothing of what the quantity means: a caller (a densification strategy) hands
it per-pixel values, and gets back their count, sum and sum of squares per dominant triangle.
"""

from __future__ import annotations

from dataclasses import dataclass

import torch
from torch import Tensor


@dataclass
class DominantSums:
    """Count, sum and sum of squares ``(F,)`` of a per-pixel quantity over the pixels a face dominates."""

    count: Tensor
    sum: Tensor
    sum_sq: Tensor

    @classmethod
    def zeros(cls, n_faces: int, dtype: torch.dtype, device: torch.device) -> DominantSums:
        """Empty sums for ``n_faces`` faces (``count`` int64, the sums ``dtype``)."""
        z = torch.zeros(n_faces, dtype=dtype, device=device)
        return cls(torch.zeros(n_faces, dtype=torch.int64, device=device), z.clone(), z.clone())

    def add(self, other: DominantSums) -> None:
        """Fold ``other`` (the same faces) into these sums, in place."""
        self.count += other.count
        self.sum += other.sum
        self.sum_sq += other.sum_sq

    def variance(self) -> Tensor:
        """``(F,)`` population variance ``E[e^2] - E[e]^2`` (0 where the count is 0)."""
        n = self.count.clamp(min=1).to(self.sum.dtype)
        return (self.sum_sq / n - (self.sum / n) ** 2).clamp(min=0)


@torch.no_grad()
def dominant_sums(dominant: Tensor, values: Tensor, valid: Tensor, n_faces: int) -> DominantSums:
    """Sums of ``values`` over the ``valid`` pixels each face dominates.

    Args:
        dominant: ``(H, W)`` int64 face with the largest weight at each pixel, -1 for none.
        values: ``(H, W)`` the per-pixel quantity (ignored where ``valid`` is False).
        valid: ``(H, W)`` bool, the pixels that count.
        n_faces: ``F``, the length of the returned sums.
    """
    if values.shape != dominant.shape or valid.shape != dominant.shape:
        raise ValueError(
            f"values {tuple(values.shape)} and valid {tuple(valid.shape)} must have the image's shape "
            f"{tuple(dominant.shape)}"
        )
    owned = valid & (dominant >= 0)
    # The pixels that do not count go to one bin past the faces': selecting the others by the
    # mask would search the image for them twice (1 ms of a 320x240 training step, for three
    # quantities). bincount sums serially on the CPU, so the sums are deterministic there.
    ids = torch.where(owned, dominant, n_faces).view(-1)
    e = torch.where(owned, values, 0.0).view(-1)
    return DominantSums(
        count=torch.bincount(ids, minlength=n_faces + 1)[:n_faces],
        sum=torch.bincount(ids, weights=e, minlength=n_faces + 1)[:n_faces].to(values.dtype),
        sum_sq=torch.bincount(ids, weights=e * e, minlength=n_faces + 1)[:n_faces].to(values.dtype),
    )
