"""Tile binning: which (16x16 tile, triangle) pairs to rasterise, in per-tile depth order."""

from __future__ import annotations

from dataclasses import dataclass
from types import ModuleType

import torch
from torch import Tensor

TILE = 16


@dataclass
class TileBins:
    """Pairs of (tile, triangle), stored twice over the same *slots*.

    Slots are numbered triangle-major (a triangle's slots are contiguous, tiles in raster order),
    so per-slot results reduce per triangle in a fixed order; ``tile_slots`` lists them tile-major
    and, inside a tile, front to back.

    Attributes:
        tile_offsets: ``(n_tiles + 1,)`` int64, entries of tile ``t`` are
            ``tile_slots[tile_offsets[t]:tile_offsets[t + 1]]``.
        tile_slots: ``(S,)`` int32 slot of each entry.
        slot_tri: ``(S,)`` int32 triangle (row of the sorted parameters) of each slot.
        tri_offsets: ``(K + 1,)`` int64 first slot of each triangle.
        tiles_x, tiles_y: tile grid size.
    """

    tile_offsets: Tensor
    tile_slots: Tensor
    slot_tri: Tensor
    tri_offsets: Tensor
    tiles_x: int
    tiles_y: int


def bin_triangles(bounds: Tensor, width: int, height: int, ext: ModuleType | None = None) -> TileBins:
    """Bin triangles (already in depth order) by the tiles their pixel boxes ``(K, 4)`` touch.

    With ``ext`` (the CPU extension) a one-pass counting sort in C++ builds the same bins; the
    PyTorch ops below are its specification and run on any device.
    """
    tiles_x, tiles_y = -(-width // TILE), -(-height // TILE)
    if ext is not None:
        tile_offsets, tile_slots, slot_tri, tri_offsets = ext.bin_triangles(bounds, width, height)
        return TileBins(tile_offsets, tile_slots, slot_tri, tri_offsets, tiles_x, tiles_y)
    device = bounds.device
    b = bounds.long()
    t0 = b[:, :2] // TILE
    span = (b[:, 2:] // TILE - t0 + 1).clamp(min=0) * (b[:, 2:] >= b[:, :2])
    counts = span[:, 0] * span[:, 1]
    tri_offsets = torch.zeros(len(b) + 1, dtype=torch.int64, device=device)
    torch.cumsum(counts, dim=0, out=tri_offsets[1:])
    slot_tri = torch.repeat_interleave(torch.arange(len(b), device=device), counts)
    local = torch.arange(len(slot_tri), device=device) - tri_offsets[slot_tri]
    width_t = span[slot_tri, 0]
    tile = (t0[slot_tri, 1] + local // width_t) * tiles_x + t0[slot_tri, 0] + local % width_t
    tile_slots = torch.sort(tile, stable=True).indices  # stable: depth order inside each tile
    tile_offsets = torch.zeros(tiles_x * tiles_y + 1, dtype=torch.int64, device=device)
    torch.cumsum(torch.bincount(tile, minlength=tiles_x * tiles_y), dim=0, out=tile_offsets[1:])
    return TileBins(
        tile_offsets=tile_offsets,
        tile_slots=tile_slots.to(torch.int32),
        slot_tri=slot_tri.to(torch.int32),
        tri_offsets=tri_offsets,
        tiles_x=tiles_x,
        tiles_y=tiles_y,
    )
