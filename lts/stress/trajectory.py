"""Trajectory-alignment stress area: the ATE of a trajectory against a rigidly moved copy of
itself, for collinear, coincident, planar and general positions at 1e-4 m to 1e4 m."""

from __future__ import annotations

import math

import numpy as np
from scipy.spatial.transform import Rotation

from eval.trajectory_metrics import absolute_trajectory_error
from rig.trajectory import Trajectory
from rig.transforms import make_transform, rotation_error


def check_alignment(positions: np.ndarray, seed: int) -> list[str]:
    """ATE of a trajectory against a rigidly moved copy of itself must be ~0, whatever the
    configuration (a line, a point, a plane: the alignment is then not unique but its residual
    is), and ``T_ref_est`` must be a rotation."""
    rng = np.random.default_rng(seed)
    n = len(positions)
    q = rng.normal(size=(n, 4))
    q /= np.linalg.norm(q, axis=1, keepdims=True)
    estimate = Trajectory.from_quaternions(np.arange(n, dtype=np.int64) * 10**8, positions, q)
    T = make_transform(Rotation.random(random_state=seed).as_matrix(), rng.normal(size=3) * 10)
    reference = estimate.transformed(T_left=T)
    scale = max(1.0, float(np.abs(positions).max()), 10.0)
    problems = []
    for use_orientation in (False, True):
        ate = absolute_trajectory_error(estimate, reference, use_orientation=use_orientation)
        if not (math.isfinite(ate.rmse_m) and ate.rmse_m <= 1e-9 * scale):
            problems.append(f"ATE {ate.rmse_m} of an exact copy (use_orientation={use_orientation})")
        if not rotation_error(ate.T_ref_est[:3, :3]) < 1e-9:
            problems.append("T_ref_est is not a rotation")
    return problems


def random_positions(rng: np.random.Generator) -> np.ndarray:
    """``(N, 3)`` positions: collinear, all equal, planar, general; 1e-4 m to 1e4 m."""
    n = int(rng.integers(3, 60))
    kind = rng.integers(4)
    scale = 10 ** rng.uniform(-4, 4)
    if kind == 0:
        p = np.outer(np.sort(rng.uniform(0, 1, n)), rng.normal(size=3))
    elif kind == 1:
        p = np.tile(rng.normal(size=3), (n, 1))
    elif kind == 2:
        p = np.c_[rng.normal(size=(n, 2)), np.zeros(n)]
    else:
        p = rng.normal(size=(n, 3))
    return p * scale + rng.normal(size=3) * scale


def stress_trajectory(rng: np.random.Generator) -> tuple[list[str], bool]:
    """Random positions and a random motion through :func:`check_alignment`: its problems, and
    ``False`` (no input is invalid on purpose)."""
    return check_alignment(random_positions(rng), int(rng.integers(2**31))), False
