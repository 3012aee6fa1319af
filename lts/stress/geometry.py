"""Geometric-metrics stress area: :func:`~eval.geometry.compare_point_sets` on empty, single,
duplicated, huge- or tiny-coordinate and NaN point sets, with good and bad thresholds."""

from __future__ import annotations

import math

import numpy as np

from eval.geometry import compare_point_sets
from rig.errors import InputError


def check_point_sets(rec: np.ndarray, gt: np.ndarray, threshold: float) -> tuple[list[str], bool]:
    """:func:`~eval.geometry.compare_point_sets` on arbitrary input: either finite metrics in
    range, or an :class:`InputError` for empty / non-finite / misshapen input or a bad threshold.
    Returns the problems and whether an input error was (rightly) raised."""
    rec, gt = np.asarray(rec, dtype=np.float64), np.asarray(gt, dtype=np.float64)
    bad_input = (
        rec.size == 0
        or gt.size == 0
        or not (np.all(np.isfinite(rec)) and np.all(np.isfinite(gt)))
        or not (math.isfinite(threshold) and threshold > 0)
    )
    try:
        m = compare_point_sets(rec, gt, threshold)
    except InputError:
        return ([] if bad_input else ["InputError on valid input"]), True
    if bad_input:
        return ["bad input gave numbers instead of an InputError"], False
    problems = []
    for name in ("precision", "recall", "fscore"):
        v = getattr(m, name)
        if not 0.0 <= v <= 1.0:
            problems.append(f"{name} {v} outside [0, 1]")
    for name in ("accuracy_m", "completeness_m", "chamfer_m"):
        v = getattr(m, name)
        if not (math.isfinite(v) and v >= 0):
            problems.append(f"{name} {v}")
    if np.array_equal(rec, gt) and not (m.chamfer_m == 0.0 and m.fscore == 1.0):
        problems.append(f"identical sets: chamfer {m.chamfer_m}, F {m.fscore}")
    return problems, False


def random_point_sets(rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray, float]:
    """Point sets (empty, single, duplicated, huge or tiny coordinates, NaN) and a threshold."""

    def points() -> np.ndarray:
        n = int(rng.choice([0, 1, 2, int(rng.integers(3, 300))]))
        p = rng.normal(size=(n, 3)) * 10 ** rng.uniform(-4, 4) + 10 ** rng.uniform(-4, 6)
        if n and rng.random() < 0.2:
            p[:] = p[0]  # all duplicates
        if n and rng.random() < 0.1:
            p[int(rng.integers(n)), int(rng.integers(3))] = float(rng.choice([np.nan, np.inf, -np.inf]))
        return p

    rec = points()
    gt = rec.copy() if rng.random() < 0.2 else points()
    threshold = float(rng.choice([0.1, 1e-6, 1e6, 0.0, -1.0, np.nan])) if rng.random() < 0.3 else 0.1
    return rec, gt, threshold


def stress_geometry(rng: np.random.Generator) -> tuple[list[str], bool]:
    """One random pair of point sets and threshold through :func:`check_point_sets`."""
    return check_point_sets(*random_point_sets(rng))
