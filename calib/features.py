"""Features shared by the targetless objectives: LiDAR discontinuity points and image edge fields.

LiDAR neighbours are found by direction (unit vectors from the sensor origin), so the detection
needs no ring index and works on any scan pattern or an accumulated cloud.
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np
from scipy.spatial import cKDTree

#: Neighbours within this angle (radians) of a point's direction are compared with it.
NEIGHBOUR_ANGLE = np.deg2rad(1.2)
NEIGHBOURS = 9
#: A range jump larger than max(MIN_JUMP_M, JUMP_FRACTION × range) is a depth discontinuity.
MIN_JUMP_M = 0.5
JUMP_FRACTION = 0.1
#: An intensity jump (sensor units, 0-255 scale) that marks a painted/reflective edge.
INTENSITY_JUMP = 30.0
MIN_RANGE_M = 1.0


@dataclass(eq=False)
class LidarEdges:
    """Discontinuity points of a cloud: ``depth`` ``(N, 3)`` and ``intensity`` ``(M, 3)`` (sensor frame)."""

    depth: np.ndarray
    intensity: np.ndarray


def lidar_edges(points: np.ndarray, intensity: np.ndarray) -> LidarEdges:
    """Foreground depth-discontinuity points and bright intensity-edge points of a cloud ``(N, 3)``.

    A depth edge is the near side of a range jump to an angular neighbour (object silhouettes);
    an intensity edge is a point brighter than all its neighbours by ``INTENSITY_JUMP`` on a
    continuous surface (lane paint, signs).
    """
    rng = np.linalg.norm(points, axis=1)
    keep = rng > MIN_RANGE_M
    points, rng, intensity = points[keep], rng[keep], intensity[keep].astype(np.float64)
    if len(points) < NEIGHBOURS:
        return LidarEdges(np.zeros((0, 3)), np.zeros((0, 3)))
    directions = points / rng[:, None]
    dist, idx = cKDTree(directions).query(directions, k=NEIGHBOURS, distance_upper_bound=NEIGHBOUR_ANGLE)
    valid = np.isfinite(dist)
    idx = np.where(valid, idx, 0)
    jump_limit = np.maximum(MIN_JUMP_M, JUMP_FRACTION * rng)
    range_gap = np.where(valid, rng[idx] - rng[:, None], -np.inf)
    depth_edge = range_gap.max(axis=1) > jump_limit
    continuous = ~np.any(valid & (np.abs(range_gap) > jump_limit[:, None]), axis=1)
    brightest_other = np.where(valid, intensity[idx], -np.inf)
    brightest_other[:, 0] = -np.inf  # the point itself
    darkest = np.where(valid, intensity[idx], np.inf).min(axis=1)
    intensity_edge = (
        continuous & (intensity - darkest > INTENSITY_JUMP) & (intensity >= brightest_other.max(axis=1))
    )
    return LidarEdges(points[depth_edge], points[intensity_edge])


def edge_field(gray: np.ndarray, sigma_px: float) -> np.ndarray:
    """Edge attraction field ``(H, W)`` float32 in [0, 1]: ``exp(-d / sigma_px)`` with ``d`` the
    distance (pixels) to the nearest Canny edge of ``gray``."""
    blurred = cv2.GaussianBlur(gray, (0, 0), 1.0)
    edges = cv2.Canny(blurred, 50, 150)
    distance = cv2.distanceTransform(255 - edges, cv2.DIST_L2, 5)
    return np.exp(-distance / sigma_px).astype(np.float32)
