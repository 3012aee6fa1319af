"""A printed chessboard calibration target as scene geometry.

Every square is its own pair of faces with a black or white material, so the pattern's corners
are exact in any pose (no texture mapping), and the LiDAR sees the print's reflectivity.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import trimesh

from rig.sim.textures import MATERIAL_IDS


@dataclass(frozen=True)
class BoardSpec:
    """A chessboard of ``cols`` × ``rows`` inner corners, squares of ``square_m``, and a white
    margin of ``margin_m`` round the squares (what ``lts calibrate --board/--square/--outline`` take)."""

    cols: int
    rows: int
    square_m: float
    margin_m: float

    @property
    def size_m(self) -> tuple[float, float]:
        """Width and height (m) of the whole board, margin included."""
        return (
            (self.cols + 1) * self.square_m + 2 * self.margin_m,
            (self.rows + 1) * self.square_m + 2 * self.margin_m,
        )


def _rectangles(corners: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Vertices ``(4R, 2)`` and faces ``(2R, 3)`` of axis-aligned rectangles ``(R, 4)`` given as
    (x0, y0, x1, y1)."""
    x0, y0, x1, y1 = corners.T
    vertices = np.stack([np.c_[x0, y0], np.c_[x1, y0], np.c_[x1, y1], np.c_[x0, y1]], axis=1).reshape(-1, 2)
    base = 4 * np.arange(len(corners))[:, None]
    faces = np.concatenate([base + np.array([0, 1, 2]), base + np.array([0, 2, 3])])
    return vertices, faces


def board_mesh(
    spec: BoardSpec, centre: tuple[float, float, float], facing_deg: float, tilt_deg: float
) -> tuple[trimesh.Trimesh, np.ndarray]:
    """The board (a mesh and each face's material index) standing at ``centre`` (world, z up),
    its printed side facing the horizontal direction ``facing_deg`` (degrees from world x),
    leaned back by ``tilt_deg`` (its normal raised towards world z)."""
    n_x, n_y = spec.cols + 1, spec.rows + 1
    s = spec.square_m
    ix, iy = np.meshgrid(np.arange(n_x), np.arange(n_y))
    x0 = (ix.ravel() - n_x / 2) * s
    y0 = (iy.ravel() - n_y / 2) * s
    squares = np.c_[x0, y0, x0 + s, y0 + s]
    black = (ix.ravel() + iy.ravel()) % 2 == 0
    hx, hy = n_x * s / 2, n_y * s / 2
    w, h = spec.size_m[0] / 2, spec.size_m[1] / 2
    margin = np.array([[-w, -h, w, -hy], [-w, hy, w, h], [-w, -hy, -hx, hy], [hx, -hy, w, hy]])
    vertices, faces = _rectangles(np.vstack([squares, margin]))
    white = MATERIAL_IDS["board_white"]
    colour = np.r_[np.where(black, MATERIAL_IDS["board_black"], white), np.full(len(margin), white)]

    facing, tilt = np.radians(facing_deg), np.radians(tilt_deg)
    forward = np.array([np.cos(facing), np.sin(facing), 0.0])
    right = np.array([np.sin(facing), -np.cos(facing), 0.0])
    up = -np.sin(tilt) * forward + np.array([0.0, 0.0, np.cos(tilt)])
    world = np.asarray(centre) + vertices[:, :1] * right + vertices[:, 1:] * up
    return trimesh.Trimesh(world, faces, process=False), np.tile(colour, 2)
