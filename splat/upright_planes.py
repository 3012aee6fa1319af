"""Camera-only cells moved onto the upright surfaces the LiDAR touched below them.

Plane-sweep stereo (:mod:`splat.plane_sweep`) gives a facade above the LiDAR's reach a depth
good to a few per cent: 1 m at 30 m, from baselines of 1.5–2 m. The LiDAR meanwhile measured the
same facade's plane to centimetres where its top beam touched it, and facades rise straight up.
A swept cell whose depth lies within :data:`~splat.plane_sweep.AGREE_FRACTION` of such a plane,
near where the plane was measured, is moved onto it: its corners slide along their pixel rays,
so it still covers the same pixels of its keyframe. On the virtual street this puts 70 % of the
snapped cells within 10 cm of the truth instead of 25 %. A tree or a sign standing within 5 % of a
facade's depth in front of it is snapped onto the facade too.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property

import numpy as np

#: A plane is used only within this distance (m) of its measured point, along the surface (a
#: facade's plane does not hold for the next building).
SNAP_ALONG_M = 3.0
#: Nor where a cell's ray meets it at a grazing angle (cosine below this): the cell would stretch.
MIN_INCIDENCE_COS = 0.25
#: Cells are matched against the planes in chunks of this many (memory: a few chunk × planes arrays).
CHUNK = 1024


@dataclass(frozen=True)
class UprightPlanes:
    """Vertical planes through LiDAR returns on upright surfaces (world frame): a return on each
    ``(P, 3)``, the unit horizontal direction along its surface ``(P, 3)``, and up ``(3,)``."""

    points: np.ndarray
    along: np.ndarray
    up: np.ndarray

    @cached_property
    def normals(self) -> np.ndarray:
        """``(P, 3)`` unit normals (horizontal), computed once for matching and moving the cells."""
        normals = np.cross(self.along, self.up)
        return normals / np.linalg.norm(normals, axis=1, keepdims=True)


def _nearest_plane(
    centres: np.ndarray, origins: np.ndarray, planes: UprightPlanes, tolerance: float
) -> np.ndarray:
    """For cells centred at ``centres`` ``(N, 3)`` seen from ``origins`` ``(N, 3)``: the index
    ``(N,)`` of the plane whose depth along the cell's ray is nearest the cell's (relative), within
    ``tolerance`` and the limits above; -1 where none qualifies."""
    normals = planes.normals
    plane_offset = np.einsum("pk,pk->p", planes.points, normals)  # (P,)
    plane_along = np.einsum("pk,pk->p", planes.points, planes.along)
    best = np.full(len(centres), -1)
    for start in range(0, len(centres), CHUNK):
        origin = origins[start : start + CHUNK]
        rays = centres[start : start + CHUNK] - origin  # (n, 3), as long as the cell's depth
        facing = rays @ normals.T  # (n, P)
        cos = np.abs(facing) / np.linalg.norm(rays, axis=1, keepdims=True)
        with np.errstate(divide="ignore", invalid="ignore"):
            scale = (plane_offset[None] - origin @ normals.T) / facing  # the plane's depth / the cell's
        # Where the ray meets the plane, measured along the surface from the plane's point.
        along = np.abs(origin @ planes.along.T + scale * (rays @ planes.along.T) - plane_along[None])
        error = np.abs(scale - 1)
        valid = (cos >= MIN_INCIDENCE_COS) & (along <= SNAP_ALONG_M) & (error <= tolerance)
        error = np.where(valid, error, np.inf)
        nearest = np.argmin(error, axis=1)
        found = np.isfinite(error[np.arange(len(nearest)), nearest])
        best[start : start + CHUNK] = np.where(found, nearest, -1)
    return best


def snap_to_planes(
    quads: np.ndarray, origins: np.ndarray, planes: UprightPlanes, tolerance: float
) -> tuple[np.ndarray, np.ndarray]:
    """Cells ``(N, 4, 3)`` (world corners) seen from camera centres ``origins`` ``(N, 3)``, each
    moved onto the plane of ``planes`` nearest its depth within the relative ``tolerance`` (its
    corners slid along their rays from the origin). Returns the cells and which moved ``(N,)``."""
    if not len(quads) or not len(planes.points):
        return quads, np.zeros(len(quads), dtype=bool)
    index = _nearest_plane(quads.mean(axis=1), origins, planes, tolerance)
    snapped = index >= 0
    normals = planes.normals[index[snapped]]  # (S, 3)
    origin = origins[snapped][:, None]  # (S, 1, 3)
    rays = quads[snapped] - origin  # (S, 4, 3)
    depth = np.einsum("sk,sk->s", planes.points[index[snapped]] - origin[:, 0], normals)
    scale = depth[:, None] / np.einsum("sck,sk->sc", rays, normals)
    moved = quads.copy()
    moved[snapped] = origin + scale[..., None] * rays
    return moved, snapped
