"""Pure-PyTorch rasteriser: the executable specification the compiled kernels are tested against.

For pixel p (centre at integer coordinates) and triangle k, in front-to-back order:

* window ratio ``m = min_j l_j(p)`` (= phi(p)/phi(s), see :mod:`splat.raster.project`),
  intensity ``I = m^sigma`` for m > 0, else the pair is skipped;
* ``alpha = min(0.99, o I)``; pairs with ``alpha < 1/255`` are skipped;
* the pixel stops (this pair and all behind it excluded) once ``T (1 - alpha) < 1e-4``;
* weight ``w = alpha T`` with ``T`` the transmittance in front of the pair;
* colour and depth of the pair are barycentric (depth perspective-correct) at p.

Outputs: rgb = sum w c, accumulated depth = sum w z, alpha = sum w, normal = sum w n, median = z
of the last composited pair with T > 0.5 in front of it (0 if none), distortion =
sum_{i<j} w_i w_j (z_i-z_j)^2 (2DGS, on camera depth), dominant = first pair with the largest w.
Autograd gives the backward.
Tiles are processed in chunks so that memory stays bounded.
"""

from __future__ import annotations

import torch
from torch import Tensor

from splat.raster.binning import TILE, TileBins
from splat.raster.images import RasterImages
from splat.raster.project import COLOR, INV_DEPTH, LINE, NORMAL, OPACITY, SIGMA

ALPHA_MIN = 1.0 / 255.0
ALPHA_MAX = 0.99
TRANSMITTANCE_MIN = 1e-4
#: Upper bound on (pixels x triangles) evaluated at once, which bounds peak memory.
CHUNK_ELEMENTS = 1 << 21


def _rasterize_tiles(params: Tensor, bins: TileBins, tiles: Tensor, width: int, height: int):
    """Composite every pixel of ``tiles`` ``(Tc,)``; per-pixel outputs are ``(Tc * 256, ...)``."""
    counts = bins.tile_offsets[tiles + 1] - bins.tile_offsets[tiles]
    n = max(int(counts.max()), 1)
    pos = torch.arange(n, device=params.device)
    valid = pos < counts[:, None]  # (Tc, n)
    entry = torch.where(valid, bins.tile_offsets[tiles, None] + pos, 0)
    tri = bins.slot_tri[bins.tile_slots[entry].long()].long()  # (Tc, n) sorted triangle rows
    prm = params[tri][:, None]  # (Tc, 1, n, 27)

    local = torch.arange(TILE * TILE, device=params.device)
    x = (tiles % bins.tiles_x * TILE)[:, None] + local % TILE  # (Tc, 256)
    y = (tiles // bins.tiles_x * TILE)[:, None] + local // TILE
    on_image = (x < width) & (y < height)
    xf, yf = x.to(params.dtype)[..., None, None], y.to(params.dtype)[..., None, None]

    lines = prm[..., LINE : LINE + 9].unflatten(-1, (3, 3))  # (Tc, 1, n, 3, 3): a, b, d per edge
    ell = lines[..., 0] * xf + lines[..., 1] * yf + lines[..., 2]  # (Tc, 256, n, 3)
    m = ell.min(dim=-1).values
    inside = valid[:, None] & on_image[..., None] & (m > 0)
    intensity = torch.where(inside, m, 1.0).pow(prm[..., SIGMA])
    alpha = (prm[..., OPACITY] * intensity).clamp(max=ALPHA_MAX)
    contributes = inside & (alpha >= ALPHA_MIN)
    alpha = torch.where(contributes, alpha, 0.0)
    t_after = torch.cumprod(1.0 - alpha, dim=-1)
    t_before = torch.cat([torch.ones_like(t_after[..., :1]), t_after[..., :-1]], dim=-1)
    included = contributes & (t_after >= TRANSMITTANCE_MIN)
    w = torch.where(included, alpha * t_before, 0.0)

    inv_depth = (ell * prm[..., INV_DEPTH : INV_DEPTH + 3]).sum(dim=-1)
    z = 1.0 / torch.where(included, inv_depth, 1.0)

    acc = w.sum(dim=-1)
    accumulated_depth = (w * z).sum(dim=-1)
    hit = acc > 0
    mean = torch.where(hit, accumulated_depth, 0.0) / torch.where(hit, acc, 1.0)
    distortion = acc * (w * (z - mean[..., None]) ** 2).sum(dim=-1)
    median_pos = torch.where(included & (t_before > 0.5), pos, -1).max(dim=-1).values
    median = torch.where(median_pos >= 0, z.gather(-1, median_pos.clamp(min=0)[..., None])[..., 0], 0.0)
    best = w.argmax(dim=-1)
    dominant = torch.where(hit, tri.gather(1, best), -1)
    flat = lambda t: t.flatten(0, 1)  # noqa: E731  (Tc, 256, ...) -> (Tc * 256, ...)
    # rgb = sum_n w_n sum_j l_nj C_nj and normal = sum_n w_n n_n, as batched matrix products.
    rgb = torch.bmm(
        (w[..., None] * ell).flatten(-2), prm[:, 0, :, COLOR : COLOR + 9].reshape(len(tiles), -1, 3)
    )
    normal = torch.bmm(w, prm[:, 0, :, NORMAL : NORMAL + 3])
    return (
        flat(rgb),
        flat(accumulated_depth),
        flat(acc),
        flat(normal),
        flat(median),
        flat(distortion),
        flat(dominant),
        tri,
        w.detach().amax(dim=1),
    )


def rasterize_reference(params: Tensor, bins: TileBins, width: int, height: int) -> RasterImages:
    """Rasterise sorted triangle parameters ``(K, 27)`` into ``height x width`` images."""
    n_tiles = bins.tiles_x * bins.tiles_y
    if len(bins.tile_slots) == 0:  # nothing visible; `params.sum() * 0` keeps the graph connected
        zero = params.sum() * 0
        blank = [zero + params.new_zeros(height, width, *c) for c in ((3,), (), (), (3,), (), ())]
        dominant = torch.full((height, width), -1, dtype=torch.int64, device=params.device)
        return RasterImages(*blank, dominant, params.new_zeros(len(params)))
    counts = (bins.tile_offsets[1:] - bins.tile_offsets[:-1]).tolist()
    parts, start = [], 0
    max_weight = torch.zeros(len(params), dtype=params.dtype, device=params.device)
    while start < n_tiles:
        stop, widest = start + 1, max(counts[start], 1)
        while (
            stop < n_tiles and (stop - start + 1) * TILE * TILE * max(widest, counts[stop]) <= CHUNK_ELEMENTS
        ):
            widest = max(widest, counts[stop])
            stop += 1
        *images, tri, w_max = _rasterize_tiles(
            params, bins, torch.arange(start, stop, device=params.device), width, height
        )
        max_weight.scatter_reduce_(0, tri.flatten(), w_max.flatten(), "amax")
        parts.append(images)
        start = stop
    # Pixel (y, x) lives at row tile(y, x) * 256 + (y % 16) * 16 + x % 16 of the tile-major stack.
    ys = torch.arange(height, device=params.device)[:, None]
    xs = torch.arange(width, device=params.device)[None, :]
    row = ((ys // TILE) * bins.tiles_x + xs // TILE) * TILE * TILE + (ys % TILE) * TILE + xs % TILE
    images = [torch.cat(channel, dim=0)[row] for channel in zip(*parts, strict=True)]
    return RasterImages(*images, max_weight)
