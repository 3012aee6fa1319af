"""Time-stamped trajectory of rigid poses with interpolation at arbitrary times."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from rig.errors import InputError, OutOfRangeError
from rig.transforms import make_transform, scipy_rotation, to_quaternion

_UNIT_QUAT_TOL = 1e-3
#: Tolerated deviation of a pose's rotation block from orthonormality and from det = 1 (files
#: print matrices to ~6 digits).
_ROTATION_TOL = 1e-2


def path_length(positions: np.ndarray) -> float:
    """Length (m) of the polyline through positions ``(N, 3)``."""
    return float(np.linalg.norm(np.diff(positions, axis=0), axis=1).sum())


@dataclass(frozen=True, eq=False)
class Trajectory:
    """Poses ``T_world_body`` at strictly increasing integer-nanosecond times.

    Rotations are held both as quaternions and as matrices, each exactly as the source gave it
    (the other is derived), so that a TUM file (quaternions) and a KITTI file (matrices) both
    write back bit-exactly. Build with :meth:`from_quaternions` or :meth:`from_poses`.

    Times must not decrease. Repeated stamps are kept (real ground truths have them, e.g. one in
    TUM fr2/desk); interpolation then uses the last pose of a repeated stamp.

    Attributes:
        t_ns: ``(N,)`` int64 timestamps in nanoseconds, strictly increasing.
        translations: ``(N, 3)`` float64 positions of the body in the world frame.
        quaternions: ``(N, 4)`` float64 orientations (x, y, z, w).
        rotations: ``(N, 3, 3)`` float64 rotation matrices.
    """

    t_ns: np.ndarray
    translations: np.ndarray
    quaternions: np.ndarray
    rotations: np.ndarray

    @staticmethod
    def _validated_times(t_ns: np.ndarray, source: str | None) -> np.ndarray:
        t_ns = np.asarray(t_ns)
        if t_ns.ndim != 1 or t_ns.size < 1:
            raise InputError("expected a non-empty 1-D array of times", path=source, field="t")
        if not np.issubdtype(t_ns.dtype, np.integer):
            raise InputError("times must be integer nanoseconds", path=source, field="t")
        t_ns = t_ns.astype(np.int64)
        backwards = np.flatnonzero(np.diff(t_ns) < 0)
        if backwards.size:
            i = int(backwards[0]) + 1
            raise InputError(
                f"out-of-order timestamp at pose {i} ({t_ns[i]} ns after {t_ns[i - 1]} ns); "
                "expected non-decreasing times",
                path=source,
                field="t",
            )
        return t_ns

    @classmethod
    def from_quaternions(
        cls,
        t_ns: np.ndarray,
        translations: np.ndarray,
        quaternions_xyzw: np.ndarray,
        *,
        source: str | None = None,
    ) -> Trajectory:
        """Trajectory from times ``(N,)`` ns, translations ``(N, 3)``, quaternions ``(N, 4)`` xyzw.

        ``source`` names the file the data came from, for error messages.
        """
        t_ns = cls._validated_times(t_ns, source)
        translations = np.asarray(translations, dtype=np.float64).reshape(-1, 3)
        quats = np.asarray(quaternions_xyzw, dtype=np.float64).reshape(-1, 4)
        if len(translations) != len(t_ns) or len(quats) != len(t_ns):
            raise InputError("times, translations and quaternions differ in length", path=source)
        norms = np.linalg.norm(quats, axis=1)
        bad = np.flatnonzero(~np.isfinite(norms) | (np.abs(norms - 1.0) > _UNIT_QUAT_TOL))
        if bad.size:
            raise InputError(
                f"quaternion of pose {int(bad[0])} has norm {norms[bad[0]]:.6g}; expected a unit quaternion",
                path=source,
                field="q",
            )
        if not np.all(np.isfinite(translations)):
            raise InputError("translation holds NaN or Inf", path=source, field="t_xyz")
        rotations = scipy_rotation().from_quat(quats).as_matrix()
        return cls(t_ns, translations, quats, rotations)

    @classmethod
    def from_poses(cls, t_ns: np.ndarray, poses: np.ndarray, *, source: str | None = None) -> Trajectory:
        """Trajectory from times ``(N,)`` ns and poses ``(N, 4, 4)`` (or ``(N, 3, 4)``)."""
        t_ns = cls._validated_times(t_ns, source)
        poses = np.asarray(poses, dtype=np.float64)
        if poses.ndim != 3 or poses.shape[1:] not in ((4, 4), (3, 4)) or len(poses) != len(t_ns):
            raise InputError(
                f"expected poses of shape ({len(t_ns)}, 4, 4), got {poses.shape}",
                path=source,
                field="pose",
            )
        if not np.all(np.isfinite(poses)):
            raise InputError("pose holds NaN or Inf", path=source, field="pose")
        if poses.shape[1] == 4:
            bad = np.flatnonzero(np.abs(poses[:, 3] - [0.0, 0.0, 0.0, 1.0]).max(axis=1) > 1e-6)
            if bad.size:
                raise InputError(
                    f"last row of pose {int(bad[0])} is {poses[bad[0], 3].tolist()}; expected [0, 0, 0, 1]",
                    path=source,
                    field="pose",
                )
        rotations = poses[:, :3, :3].copy()
        dets = np.linalg.det(rotations)
        # Orthonormality too, not only the determinant: a shear with det 1 is no rotation, and a
        # quaternion taken from it would be a confident wrong orientation.
        skew = np.abs(rotations @ rotations.transpose(0, 2, 1) - np.eye(3)).max(axis=(1, 2))
        bad = np.flatnonzero((np.abs(dets - 1.0) > _ROTATION_TOL) | (skew > _ROTATION_TOL))
        if bad.size:
            i = int(bad[0])
            raise InputError(
                f"rotation of pose {i} has determinant {dets[i]:.6g} and |R Rᵀ - I| = {skew[i]:.3g}; "
                f"expected a rotation (within {_ROTATION_TOL:g})",
                path=source,
                field="pose",
            )
        return cls(t_ns, poses[:, :3, 3].copy(), to_quaternion(poses), rotations)

    def __len__(self) -> int:
        return len(self.t_ns)

    @property
    def poses(self) -> np.ndarray:
        """``(N, 4, 4)`` poses ``T_world_body``."""
        return make_transform(self.rotations, self.translations)

    @property
    def t_start_ns(self) -> int:
        return int(self.t_ns[0])

    @property
    def t_end_ns(self) -> int:
        return int(self.t_ns[-1])

    @property
    def duration_s(self) -> float:
        return (self.t_end_ns - self.t_start_ns) * 1e-9

    @property
    def path_length_m(self) -> float:
        """Length of the path through the positions (m)."""
        return path_length(self.translations)

    def covers(self, t_ns: np.ndarray | int) -> np.ndarray:
        """Boolean mask ``(M,)`` (or scalar): which query times lie within the trajectory's span."""
        t = np.asarray(t_ns, dtype=np.int64)
        return (t >= self.t_start_ns) & (t <= self.t_end_ns)

    def interpolate(self, t_ns: np.ndarray | int, *, clamp: bool = False) -> np.ndarray:
        """Poses at query times: SLERP for rotation, linear for translation.

        Args:
            t_ns: query times in ns, scalar or ``(M,)``.
            clamp: hold the first/last pose outside the span instead of raising.

        Returns:
            ``(4, 4)`` for a scalar query, else ``(M, 4, 4)``. At a knot time the knot pose is
            returned exactly.

        Raises:
            OutOfRangeError: a query lies outside ``[t_start, t_end]`` and ``clamp`` is false.
        """
        scalar = np.ndim(t_ns) == 0
        t = np.atleast_1d(np.asarray(t_ns, dtype=np.int64))
        outside = ~self.covers(t)
        if outside.any() and not clamp:
            raise OutOfRangeError(
                f"{int(outside.sum())} query time(s) outside the trajectory "
                f"[{self.t_start_ns}, {self.t_end_ns}] ns (first: {int(t[outside][0])} ns); "
                "pass clamp=True to hold the end poses"
            )
        t = np.clip(t, self.t_start_ns, self.t_end_ns)
        last = len(self) - 1
        # i: the last knot at or before each query; a query on a knot copies it rather than blending.
        i = np.searchsorted(self.t_ns, t, side="right") - 1
        exact = self.t_ns[i] == t
        out_R = np.empty((len(t), 3, 3))
        out_p = np.empty((len(t), 3))
        out_R[exact] = self.rotations[i[exact]]
        out_p[exact] = self.translations[i[exact]]
        blend = ~exact
        if blend.any():
            i0 = i[blend]
            i1 = np.minimum(i0 + 1, last)
            t0 = self.t_ns[i0]
            frac = ((t[blend] - t0) / (self.t_ns[i1] - t0))[:, None]
            out_p[blend] = (1.0 - frac) * self.translations[i0] + frac * self.translations[i1]
            Rotation = scipy_rotation()
            R0 = Rotation.from_matrix(self.rotations[i0])
            step = (R0.inv() * Rotation.from_matrix(self.rotations[i1])).as_rotvec()
            out_R[blend] = (R0 * Rotation.from_rotvec(frac * step)).as_matrix()
        poses = make_transform(out_R, out_p)
        return poses[0] if scalar else poses

    def transformed(self, T_left: np.ndarray | None = None, T_right: np.ndarray | None = None) -> Trajectory:
        """Trajectory of ``T_left @ T_i @ T_right`` (e.g. change of world frame / body frame)."""
        poses = self.poses
        if T_left is not None:
            poses = np.asarray(T_left) @ poses
        if T_right is not None:
            poses = poses @ np.asarray(T_right)
        return Trajectory.from_poses(self.t_ns, poses)
