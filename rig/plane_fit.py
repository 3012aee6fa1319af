"""A seeded RANSAC plane fit, shared by the LiDAR board planes (calib) and the floor (splat).

Written out with numpy because open3d's parallel ``segment_plane`` returned different planes
from run to run despite ``o3d.utility.random.seed`` (the board extrinsic moved by up to 0.1°, and
two trainings of the same config differed by their floor).
"""

from __future__ import annotations

import numpy as np


def ransac_plane(
    points: np.ndarray, threshold_m: float, iterations: int = 500, seed: int = 0, max_support: int = 20_000
) -> tuple[np.ndarray, np.ndarray]:
    """Unit-normal plane ``(4,)`` (``n·x + d = 0``, refined by least squares on the inliers) and
    the inlier indices of the points ``(N, 3)`` within ``threshold_m`` of the best-supported of
    ``iterations`` seeded three-point planes. Hypotheses are scored on at most ``max_support``
    points (memory grows as iterations × support); inliers are taken from all of them. No
    hypothesis (fewer than three distinct points): a zero plane and no inliers."""
    rng = np.random.default_rng(seed)
    sample = points
    if len(points) > max_support:
        sample = points[rng.choice(len(points), max_support, replace=False)]
    triples = sample[rng.integers(0, len(sample), (iterations, 3))]  # (I, 3, 3)
    normals = np.cross(triples[:, 1] - triples[:, 0], triples[:, 2] - triples[:, 0])
    length = np.linalg.norm(normals, axis=1)
    ok = length > 1e-12
    if not ok.any():
        return np.zeros(4), np.zeros(0, dtype=np.int64)
    normals, triples = normals[ok] / length[ok, None], triples[ok]
    offsets = -np.einsum("ij,ij->i", normals, triples[:, 0])
    support = (np.abs(sample @ normals.T + offsets) < threshold_m).sum(axis=0)
    best = int(np.argmax(support))
    inliers = np.flatnonzero(np.abs(points @ normals[best] + offsets[best]) < threshold_m)
    centre = points[inliers].mean(axis=0)
    normal = np.linalg.svd(points[inliers] - centre, full_matrices=False)[2][2]
    return np.append(normal, -normal @ centre), inliers
