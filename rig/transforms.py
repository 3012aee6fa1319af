"""Rigid transforms as 4×4 numpy matrices.

``T_a_b`` maps points in frame ``b`` to frame ``a``: ``p_a = T_a_b @ p_b``. Every function accepts
one transform ``(4, 4)`` or a stack ``(N, 4, 4)``.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from rig.errors import InputError

#: Largest tolerated deviation of ``R @ R.T`` from the identity, and of ``det R`` from 1.
ORTHONORMAL_TOL = 1e-6


def make_transform(rotation: np.ndarray, translation: np.ndarray) -> np.ndarray:
    """Build ``(..., 4, 4)`` transforms from rotations ``(..., 3, 3)`` and translations ``(..., 3)``."""
    rotation = np.asarray(rotation, dtype=np.float64)
    translation = np.asarray(translation, dtype=np.float64)
    batch = rotation.shape[:-2]
    T = np.zeros((*batch, 4, 4))
    T[..., :3, :3] = rotation
    T[..., :3, 3] = translation
    T[..., 3, 3] = 1.0
    return T


def invert(T: np.ndarray) -> np.ndarray:
    """Inverse of rigid transforms ``(..., 4, 4)``, using ``R.T`` rather than a general inverse."""
    T = np.asarray(T, dtype=np.float64)
    R_inv = np.swapaxes(T[..., :3, :3], -1, -2)
    t_inv = -np.einsum("...ij,...j->...i", R_inv, T[..., :3, 3])
    return make_transform(R_inv, t_inv)


def transform_points(T: np.ndarray, points: np.ndarray) -> np.ndarray:
    """Apply one transform ``(4, 4)`` to points ``(N, 3)``; returns ``(N, 3)`` in float64."""
    points = np.asarray(points, dtype=np.float64)
    return points @ T[:3, :3].T + T[:3, 3]


def scipy_rotation() -> Any:
    """SciPy's ``Rotation`` class, imported when first needed: scipy.spatial takes ~0.4 s to
    import, and every command line (``lts --help`` too) imports the modules that use it."""
    from scipy.spatial.transform import Rotation

    return Rotation


def distance_and_angle(T_a: np.ndarray, T_b: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """How far apart two poses are: the distance (m) between their positions and the angle (rad)
    between their orientations. ``T_a``, ``T_b``: ``(..., 4, 4)`` (broadcast); returns two arrays of
    the broadcast leading shape (0-d for single poses: ``float()`` them)."""
    T_a, T_b = np.broadcast_arrays(np.asarray(T_a, dtype=np.float64), np.asarray(T_b, dtype=np.float64))
    distance = np.linalg.norm(T_a[..., :3, 3] - T_b[..., :3, 3], axis=-1)
    relative = np.swapaxes(T_b[..., :3, :3], -1, -2) @ T_a[..., :3, :3]
    angle = scipy_rotation().from_matrix(relative.reshape(-1, 3, 3)).magnitude().reshape(distance.shape)
    return distance, angle


def from_quaternion(quat_xyzw: np.ndarray, translation: np.ndarray) -> np.ndarray:
    """Transforms ``(..., 4, 4)`` from unit quaternions ``(..., 4)`` (x, y, z, w) and translations."""
    quat_xyzw = np.asarray(quat_xyzw, dtype=np.float64)
    rotation = scipy_rotation().from_quat(quat_xyzw.reshape(-1, 4)).as_matrix()
    return make_transform(rotation.reshape(*quat_xyzw.shape[:-1], 3, 3), translation)


def to_quaternion(T: np.ndarray) -> np.ndarray:
    """Unit quaternions ``(..., 4)`` (x, y, z, w, with w >= 0) of transforms ``(..., 4, 4)``."""
    T = np.asarray(T, dtype=np.float64)
    quat = scipy_rotation().from_matrix(T[..., :3, :3].reshape(-1, 3, 3)).as_quat(canonical=True)
    return quat.reshape(*T.shape[:-2], 4)


def rotation_error(R: np.ndarray) -> float:
    """Largest deviation of ``R`` ``(3, 3)`` from a proper rotation (orthonormality and det)."""
    R = np.asarray(R, dtype=np.float64)
    return float(max(np.abs(R @ R.T - np.eye(3)).max(), abs(np.linalg.det(R) - 1.0)))


def check_rigid(T: np.ndarray, *, field: str, path: str | None = None) -> np.ndarray:
    """Return ``T`` as a float64 ``(4, 4)`` array, or raise :class:`InputError` naming ``field``.

    Checks the shape, finiteness, the last row ``[0, 0, 0, 1]`` and that the rotation block is
    orthonormal with determinant +1 (within :data:`ORTHONORMAL_TOL`).
    """
    try:
        T = np.asarray(T, dtype=np.float64)
    except (TypeError, ValueError) as exc:
        raise InputError(f"expected a 4x4 numeric matrix ({exc})", path=path, field=field) from None
    if T.shape != (4, 4):
        raise InputError(f"expected a 4x4 matrix, got shape {T.shape}", path=path, field=field)
    if not np.all(np.isfinite(T)):
        raise InputError("matrix holds NaN or Inf", path=path, field=field)
    if not np.allclose(T[3], [0.0, 0.0, 0.0, 1.0], atol=1e-9):
        raise InputError(f"last row must be [0, 0, 0, 1], got {T[3].tolist()}", path=path, field=field)
    err = rotation_error(T[:3, :3])
    if err > ORTHONORMAL_TOL:
        raise InputError(
            f"rotation block is not orthonormal with det +1 (deviation {err:.2e} > {ORTHONORMAL_TOL:g})",
            path=path,
            field=field,
        )
    return T
