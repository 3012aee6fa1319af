"""A seeded RANSAC plane fit, shared by the LiDAR board planes (calib) and the floor (splat),
a refinement of its inliers for noisy points, and the least-squares plane both use.

Written out with numpy because open3d's parallel ``segment_plane`` returned different planes
from run to run despite ``o3d.utility.random.seed`` (the board extrinsic moved by up to 0.1°, and
two trainings of the same config differed by their floor).
"""

from __future__ import annotations

import numpy as np


def ransac_plane(
    points: np.ndarray,
    threshold_m: float,
    iterations: int = 500,
    seed: int = 0,
    max_support: int = 20_000,
    normal_near: tuple[np.ndarray, float] | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """Unit-normal plane ``(4,)`` (``n·x + d = 0``, refined by least squares on the inliers) and
    the inlier indices of the points ``(N, 3)`` within ``threshold_m`` of the best-supported of
    ``iterations`` seeded three-point planes. Hypotheses are scored on at most ``max_support``
    points (memory grows as iterations × support); inliers are taken from all of them.
    ``normal_near`` (a unit axis ``(3,)``, degrees): only hypotheses whose normal is within that
    angle of the axis, either way (the floor among walls). No hypothesis (fewer than three
    distinct points, or none near the axis): a zero plane and no inliers."""
    rng = np.random.default_rng(seed)
    sample = points
    if len(points) > max_support:
        sample = points[rng.choice(len(points), max_support, replace=False)]
    triples = sample[rng.integers(0, len(sample), (iterations, 3))]  # (I, 3, 3)
    normals = np.cross(triples[:, 1] - triples[:, 0], triples[:, 2] - triples[:, 0])
    length = np.linalg.norm(normals, axis=1)
    ok = length > 1e-12
    if normal_near is not None:
        axis, max_deg = normal_near
        ok &= np.abs(normals @ axis) >= np.cos(np.radians(max_deg)) * length
    if not ok.any():
        return np.zeros(4), np.zeros(0, dtype=np.int64)
    normals, triples = normals[ok] / length[ok, None], triples[ok]
    offsets = -np.einsum("ij,ij->i", normals, triples[:, 0])
    support = (np.abs(sample @ normals.T + offsets) < threshold_m).sum(axis=0)
    best = int(np.argmax(support))
    inliers = np.flatnonzero(np.abs(points @ normals[best] + offsets[best]) < threshold_m)
    return least_squares_plane(points[inliers]), inliers


def refine_plane(
    points: np.ndarray,
    inliers: np.ndarray,
    threshold_m: float,
    n_sigma: float = 3.0,
    max_iterations: int = 10,
) -> tuple[np.ndarray, np.ndarray]:
    """Least-squares plane ``(4,)`` (``n·x + d = 0``) of points ``(N, 3)`` and its inlier indices,
    from a first inlier set (RANSAC's): repeatedly the plane through the inliers, then the points
    within ``n_sigma`` robust standard deviations (1.4826 × the median distance) of it, but at
    least ``threshold_m``, until the set stops changing.

    RANSAC's inliers lie within ``threshold_m`` of a three-point plane; when that is only about
    twice the noise, the set is cut off around that plane and the least-squares plane through it
    leans towards it (LiDAR board planes of the virtual rig, 1.5 cm range noise, 2 cm threshold:
    0.32–0.44° rms per plane, 0.28–0.31° after this refinement)."""
    plane = least_squares_plane(points[inliers])
    for _ in range(max_iterations):
        distance = np.abs(points @ plane[:3] + plane[3])
        sigma = 1.4826 * np.median(distance[inliers])
        refined = np.flatnonzero(distance <= max(n_sigma * sigma, threshold_m))
        if np.array_equal(refined, inliers):
            break
        inliers = refined
        plane = least_squares_plane(points[inliers])
    return plane, inliers


def least_squares_plane(points: np.ndarray) -> np.ndarray:
    """Unit-normal plane ``(4,)`` (``n·x + d = 0``) through points ``(M, 3)`` (M >= 3), least squares."""
    centre = points.mean(axis=0)
    normal = np.linalg.svd(points - centre, full_matrices=False)[2][2]
    return np.append(normal, -normal @ centre)
