"""Trajectory accuracy: absolute trajectory error after rigid alignment (as evo's APE does)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from rig.errors import InputError
from rig.trajectory import Trajectory
from rig.transforms import distance_and_angle, make_transform, transform_points


def _matched(source: np.ndarray, target: np.ndarray, item: tuple[int, ...]) -> tuple[np.ndarray, np.ndarray]:
    """Both arrays as float64 ``(N, *item)``, equally long and finite (an SVD of NaN does not
    converge: a raw LinAlgError otherwise)."""
    source, target = np.asarray(source, dtype=np.float64), np.asarray(target, dtype=np.float64)
    for name, a in (("source", source), ("target", target)):
        if a.ndim != 1 + len(item) or a.shape[1:] != item:
            raise InputError(f"expected shape (N, {', '.join(map(str, item))}), got {a.shape}", field=name)
        if not np.all(np.isfinite(a)):
            raise InputError("holds NaN or Inf", field=name)
    if len(source) != len(target):
        raise InputError(f"{len(source)} source against {len(target)} target entries", field="trajectory")
    return source, target


def umeyama_alignment(source: np.ndarray, target: np.ndarray) -> np.ndarray:
    """Rigid transform ``(4, 4)`` minimising ``Σ |T · source_i − target_i|²`` for points ``(N, 3)``
    (Umeyama 1991, without scale).

    Positions on a line (or all at one point) leave the rotation about that line (or any
    rotation) free: the residuals, and so the ATE, are still right, but the returned rotation is
    one of many; use :func:`pose_alignment` when the transform itself matters.
    """
    source, target = _matched(source, target, (3,))
    if len(source) < 3:
        raise InputError("need at least 3 matched positions to align trajectories", field="trajectory")
    mu_s, mu_t = source.mean(axis=0), target.mean(axis=0)
    U, _, Vt = np.linalg.svd((target - mu_t).T @ (source - mu_s))
    D = np.eye(3)
    D[2, 2] = np.sign(np.linalg.det(U @ Vt))
    R = U @ D @ Vt
    return make_transform(R, mu_t - R @ mu_s)


def pose_alignment(source: np.ndarray, target: np.ndarray) -> np.ndarray:
    """Rigid transform ``(4, 4)`` taking poses ``source`` ``(N, 4, 4)`` onto ``target``, using the
    orientations too: the chordal mean of ``R_target_i R_source_iᵀ``, then the mean translation.

    Unlike :func:`umeyama_alignment`, this stays well conditioned when the positions lie near a
    line (a robot driving mostly straight), where a position-only fit leaves the rotation about
    that line free — and a small rotation error there moves distant map points by centimetres.
    """
    source, target = _matched(source, target, (4, 4))
    if len(source) < 1:
        raise InputError("need at least one matched pose to align trajectories", field="trajectory")
    M = np.einsum("nij,nkj->ik", target[:, :3, :3], source[:, :3, :3])
    U, _, Vt = np.linalg.svd(M)
    D = np.eye(3)
    D[2, 2] = np.sign(np.linalg.det(U @ Vt))
    R = U @ D @ Vt
    return make_transform(R, np.mean(target[:, :3, 3] - source[:, :3, 3] @ R.T, axis=0))


@dataclass(frozen=True)
class AbsoluteTrajectoryError:
    """Position error statistics (m) after aligning the estimate to the reference with ``T_ref_est``."""

    rmse_m: float
    mean_m: float
    max_m: float
    poses: int
    T_ref_est: np.ndarray


def absolute_trajectory_error(
    estimate: Trajectory, reference: Trajectory, use_orientation: bool = False
) -> AbsoluteTrajectoryError:
    """ATE of ``estimate`` against ``reference``, compared at the estimate's stamps that the
    reference covers (the reference interpolated there).

    Args:
        use_orientation: align with :func:`pose_alignment` (positions and orientations) instead of
            the position-only Umeyama fit evo uses by default.
    """
    covered = reference.covers(estimate.t_ns)
    if covered.sum() < 3:
        raise InputError("the reference trajectory covers fewer than 3 of the estimate's stamps", field="t")
    est = estimate.translations[covered]
    ref_poses = reference.interpolate(estimate.t_ns[covered])
    ref = ref_poses[:, :3, 3]
    T = pose_alignment(estimate.poses[covered], ref_poses) if use_orientation else umeyama_alignment(est, ref)
    errors = np.linalg.norm(transform_points(T, est) - ref, axis=1)
    return AbsoluteTrajectoryError(
        float(np.sqrt(np.mean(errors**2))), float(errors.mean()), float(errors.max()), int(covered.sum()), T
    )


@dataclass(frozen=True)
class RelativePoseError:
    """Error of the motion between poses ``delta`` apart (evo's RPE, both parts), after no
    alignment: translation (m) and rotation (deg) RMSE and maximum over the pairs."""

    translation_rmse_m: float
    translation_max_m: float
    rotation_rmse_deg: float
    rotation_max_deg: float
    pairs: int
    delta: int


def relative_pose_error(estimate: Trajectory, reference: Trajectory, delta: int = 1) -> RelativePoseError:
    """RPE of ``estimate`` against ``reference`` (interpolated at the estimate's stamps it covers)
    over pose pairs ``delta`` apart: the error ``(Q_i⁻¹ Q_j)⁻¹ (P_i⁻¹ P_j)`` of each relative motion."""
    if delta < 1:
        raise InputError(f"must be at least 1, got {delta}", field="delta")
    covered = reference.covers(estimate.t_ns)
    if covered.sum() <= delta:
        raise InputError(
            f"the reference covers {int(covered.sum())} of the estimate's stamps; need more than {delta}",
            field="t",
        )
    est = estimate.poses[covered]
    ref = reference.interpolate(estimate.t_ns[covered])
    # The error's translation and angle are the distance and angle between the two motions.
    translation, angle = distance_and_angle(
        np.linalg.inv(est[:-delta]) @ est[delta:], np.linalg.inv(ref[:-delta]) @ ref[delta:]
    )
    rotation = np.degrees(angle)
    return RelativePoseError(
        float(np.sqrt(np.mean(translation**2))), float(translation.max()),
        float(np.sqrt(np.mean(rotation**2))), float(rotation.max()), len(translation), delta,
    )  # fmt: skip
