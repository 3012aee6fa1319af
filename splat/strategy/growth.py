"""New rows for a densified triangle: two clones or four midpoint children."""

from __future__ import annotations

import torch
from torch import Tensor

from splat.model import LOGIT_LIMIT, TriangleModel, logit


def cloned_rows(model: TriangleModel, rows: Tensor) -> dict[str, Tensor]:
    """Two copies of each of ``rows`` ``(K,)`` (``2K`` rows per parameter, copy-major), each with
    opacity ``1 - sqrt(1 - o)`` so that together they let through what the original did."""
    p = model.params
    o = torch.sigmoid(p["opacity"].detach()[rows])
    return {
        "vertices": p["vertices"].detach()[rows].repeat(2, 1, 1),
        "colors": p["colors"].detach()[rows].repeat(2, 1, 1),
        "opacity": logit(1 - torch.sqrt(1 - o)).to(o).repeat(2),
    }


def subdivided_rows(model: TriangleModel, rows: Tensor) -> dict[str, Tensor]:
    """The 4 midpoint triangles of each of ``rows`` ``(K,)`` (``4K`` rows per parameter,
    child-major), colours interpolated."""
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
