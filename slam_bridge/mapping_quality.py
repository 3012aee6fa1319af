"""How far a fallback-mapper trajectory can be trusted: a verdict like calibration's.

Two things make LiDAR odometry doubtful on real drives, and each is measured while mapping:
- **moving objects**: the trajectory is registered twice, with every point and then with the
  static points only (:mod:`rig.dynamic_points`); where many points moved and the two
  differ by more than :data:`MAX_DYNAMIC_SHIFT_M` (or :data:`MAX_DYNAMIC_SHIFT_FRACTION` of the
  path), traffic pulled the first, and the moving points were found with its poses;
- **degenerate geometry**: sweeps whose surface normals leave a translation direction nearly
  unconstrained (a featureless tunnel, an open road with only the ground and parallel facades);
and two registration statistics are reported beside them: how far registration moved each pose
from the constant-velocity prediction, and the fraction of each sweep's points that found a map
voxel.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from rig.trajectory import path_length

#: A sweep whose smallest translation-information eigenvalue (of three summing to 1) is below this
#: has a degenerate direction. Measured medians (10th percentile): virtual room 0.27 (0.26),
#: corridor 0.20 (0.18), street 0.12 (0.10, along the road); a surface-free direction gives ~0.
DEGENERATE_INFORMATION = 0.05
#: More than this fraction of degenerate sweeps makes the trajectory doubtful.
MAX_DEGENERATE_FRACTION = 0.2
#: The two trajectories differ also where nothing moves (the second registers de-skewed sweeps:
#: 0.03 m on the virtual street without traffic, 0.025 m in the room; with traffic, 31 % of the
#: points moving, 0.045 m over 55.6 m), so the shift counts only with at least
#: :data:`MIN_DYNAMIC_FRACTION` of the points moving.
MAX_DYNAMIC_SHIFT_M = 0.05
MAX_DYNAMIC_SHIFT_FRACTION = 0.005
MIN_DYNAMIC_FRACTION = 0.02


@dataclass
class MappingQuality:
    """The mapper's verdict on its trajectory, with the numbers behind it.

    Attributes:
        verdict: ``ok`` or ``doubtful``.
        reasons: one sentence per doubt (empty when ``ok``).
        dynamic_fraction: fraction of the points judged moving (left out of the map).
        dynamic_shift_m: largest distance between the all-points and the static-points trajectory
            (0 when moving objects are not removed).
        degenerate_fraction: fraction of sweeps with a nearly unconstrained translation direction.
        weakest_direction: ``[x, y, z]`` the most often weak direction (world frame), or None.
        correction_m: median and maximum distance between a sweep's constant-velocity prediction
            and its registered position.
        inlier_fraction: median and minimum fraction of a sweep's points that found a map voxel.
    """

    verdict: str
    reasons: list[str] = field(default_factory=list)
    dynamic_fraction: float = 0.0
    dynamic_shift_m: float = 0.0
    degenerate_fraction: float = 0.0
    weakest_direction: list[float] | None = None
    correction_m: tuple[float, float] = (0.0, 0.0)
    inlier_fraction: tuple[float, float] = (0.0, 0.0)


def judge_mapping(
    raw_positions: np.ndarray,
    static_positions: np.ndarray,
    dynamic_fraction: float,
    translation_information: np.ndarray,
    weakest_directions: np.ndarray,
    corrections_m: np.ndarray,
    inlier_fractions: np.ndarray,
) -> MappingQuality:
    """The verdict on a trajectory from per-sweep records: positions ``(S, 3)`` registered with all
    points and with static points only (the same when no removal ran), the smallest
    translation-information eigenvalue ``(S,)`` and its direction ``(S, 3)`` (world frame), and
    the registration's correction of the prediction ``(S,)`` (m) and inlier fraction ``(S,)``."""
    path = path_length(static_positions)
    shift = (
        float(np.linalg.norm(raw_positions - static_positions, axis=1).max()) if len(raw_positions) else 0.0
    )
    degenerate = translation_information < DEGENERATE_INFORMATION
    weakest = None
    if degenerate.any():
        # Sign-free average of the weak directions: the principal axis of their outer products.
        d = weakest_directions[degenerate]
        weakest = np.round(np.linalg.eigh(d.T @ d)[1][:, -1], 3).tolist()
    reasons = []
    if dynamic_fraction >= MIN_DYNAMIC_FRACTION and shift > max(
        MAX_DYNAMIC_SHIFT_M, MAX_DYNAMIC_SHIFT_FRACTION * path
    ):
        reasons.append(
            f"{100 * dynamic_fraction:.1f} % of the points moved, and the trajectories registered with and "
            f"without them differ by up to {shift:.2f} m over a {path:.1f} m path: the one without them is "
            "used, but which points moved was judged with the other"
        )
    if degenerate.mean() > MAX_DEGENERATE_FRACTION:
        reasons.append(
            f"{100 * degenerate.mean():.0f} % of the sweeps barely constrain translation along {weakest} "
            "(a tunnel or an open road): distances along it may be short or long"
        )
    return MappingQuality(
        "doubtful" if reasons else "ok", reasons, dynamic_fraction, shift, float(degenerate.mean()), weakest,
        (float(np.median(corrections_m)), float(corrections_m.max())),
        (float(np.median(inlier_fractions)), float(inlier_fractions.min())),
    )  # fmt: skip
