"""Continuous-time rigid motion: a cubic position spline and a cubic rotation spline.

Every sensor of the virtual rig samples the same :class:`Motion` of the camera, so poses at
arbitrary times (per LiDAR point, per IMU sample) and their derivatives are consistent.
"""

from __future__ import annotations

import numpy as np
from scipy.interpolate import CubicSpline
from scipy.spatial.transform import Rotation, RotationSpline

from rig.errors import InputError
from rig.trajectory import Trajectory
from rig.transforms import make_transform

#: Step of the central differences that give velocities and accelerations of derived frames (s).
DIFF_STEP_S = 1e-3


class Motion:
    """Pose ``T_world_cam(t)`` for ``t`` in seconds on ``[0, duration_s]``.

    Args:
        t_s: ``(K,)`` strictly increasing knot times in seconds, starting at 0.
        positions: ``(K, 3)`` camera positions in the world.
        rotations: ``(K, 3, 3)`` camera-to-world rotations.
        at_rest: start and end with zero velocity (clamped spline) instead of natural ends.
    """

    def __init__(
        self, t_s: np.ndarray, positions: np.ndarray, rotations: np.ndarray, *, at_rest: bool
    ) -> None:
        t_s = np.asarray(t_s, dtype=np.float64)
        if len(t_s) < 2:
            raise InputError(f"a trajectory needs at least 2 poses, got {len(t_s)}", field="trajectory")
        if np.any(np.diff(t_s) <= 0):
            raise InputError("trajectory times must increase strictly", field="trajectory")
        self.duration_s = float(t_s[-1] - t_s[0])
        self._t0 = float(t_s[0])
        self._position = CubicSpline(t_s - self._t0, positions, bc_type="clamped" if at_rest else "natural")
        self._rotation = RotationSpline(t_s - self._t0, Rotation.from_matrix(rotations))

    @classmethod
    def from_trajectory(cls, trajectory: Trajectory, source: str | None = None) -> Motion:
        """Spline through the poses of a trajectory (repeated stamps keep their last pose);
        ``source`` names the file in errors."""
        last_of_stamp = np.append(np.diff(trajectory.t_ns) > 0, True)
        t_s = (trajectory.t_ns[last_of_stamp] - trajectory.t_ns[0]) * 1e-9
        if len(t_s) < 2:
            raise InputError(
                f"a trajectory needs at least 2 poses at distinct times, got {len(t_s)}",
                path=source,
                field="trajectory",
            )
        return cls(
            t_s, trajectory.translations[last_of_stamp], trajectory.rotations[last_of_stamp], at_rest=False
        )

    def positions(self, t_s: np.ndarray) -> np.ndarray:
        """Camera positions ``(N, 3)`` at times ``(N,)``."""
        return self._position(np.asarray(t_s, dtype=np.float64))

    def rotations(self, t_s: np.ndarray) -> np.ndarray:
        """Camera-to-world rotations ``(N, 3, 3)`` at times ``(N,)``."""
        return self._rotation(np.asarray(t_s, dtype=np.float64)).as_matrix()

    def poses(self, t_s: np.ndarray, T_cam_sensor: np.ndarray | None = None) -> np.ndarray:
        """Poses ``T_world_sensor`` ``(N, 4, 4)`` at times ``(N,)`` of a sensor rigidly mounted at
        ``T_cam_sensor`` ``(4, 4)`` (the camera itself when None)."""
        T = make_transform(self.rotations(t_s), self.positions(t_s))
        return T if T_cam_sensor is None else T @ T_cam_sensor

    def kinematics(
        self, t_s: np.ndarray, T_cam_sensor: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Rotation ``(N, 3, 3)``, body-frame angular velocity ``(N, 3)`` rad/s and world-frame
        acceleration ``(N, 3)`` m/s² of a sensor mounted at ``T_cam_sensor`` (central differences,
        so lever-arm effects are included)."""
        t = np.asarray(t_s, dtype=np.float64)
        h = DIFF_STEP_S
        before, now, after = (self.poses(t + dt, T_cam_sensor) for dt in (-h, 0.0, h))
        relative = np.einsum("nji,njk->nik", before[:, :3, :3], after[:, :3, :3])
        omega = Rotation.from_matrix(relative).as_rotvec() / (2 * h)
        accel = (after[:, :3, 3] - 2 * now[:, :3, 3] + before[:, :3, 3]) / h**2
        return now[:, :3, :3], omega, accel

    def trajectory(
        self, t_s: np.ndarray, stamps_ns: np.ndarray, T_cam_sensor: np.ndarray | None = None
    ) -> Trajectory:
        """Poses of a sensor at times ``t_s`` ``(N,)`` as a :class:`Trajectory` stamped ``stamps_ns``."""
        return Trajectory.from_poses(np.asarray(stamps_ns, dtype=np.int64), self.poses(t_s, T_cam_sensor))
