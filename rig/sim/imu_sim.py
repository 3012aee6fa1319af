"""IMU simulation: gyro and accelerometer readings from the trajectory's derivatives."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from rig.sim.motion import Motion

#: Gravity in the world frame (z up), m/s².
GRAVITY = np.array([0.0, 0.0, -9.81])


@dataclass(frozen=True)
class ImuModel:
    """Noise model: white noise std per sample and a constant bias drawn once per run.

    Attributes:
        rate_hz: samples per second.
        gyro_noise, accel_noise: per-sample std (rad/s, m/s²).
        gyro_bias_std, accel_bias_std: std of the constant biases (rad/s, m/s²).
    """

    rate_hz: float = 200.0
    gyro_noise: float = 0.003
    accel_noise: float = 0.03
    gyro_bias_std: float = 0.002
    accel_bias_std: float = 0.05


@dataclass
class ImuReadings:
    """``N`` IMU samples: angular velocity ``(N, 3)`` rad/s and specific force ``(N, 3)`` m/s² in
    the IMU frame, and the biases ``(3,)`` that were added."""

    gyro: np.ndarray
    accel: np.ndarray
    gyro_bias: np.ndarray
    accel_bias: np.ndarray


def simulate_imu(
    motion: Motion, imu: ImuModel, T_cam_imu: np.ndarray, t_s: np.ndarray, rng: np.random.Generator
) -> ImuReadings:
    """Readings at times ``t_s`` ``(N,)`` of an IMU mounted at ``T_cam_imu`` ``(4, 4)``.

    The accelerometer measures specific force ``R^T (a - g)``; both sensors add bias and noise.
    """
    R, omega, accel_world = motion.kinematics(t_s, T_cam_imu)
    specific_force = np.einsum("nji,nj->ni", R, accel_world - GRAVITY)
    gyro_bias = imu.gyro_bias_std * rng.standard_normal(3)
    accel_bias = imu.accel_bias_std * rng.standard_normal(3)
    n = len(t_s)
    gyro = omega + gyro_bias + imu.gyro_noise * rng.standard_normal((n, 3))
    accel = specific_force + accel_bias + imu.accel_noise * rng.standard_normal((n, 3))
    return ImuReadings(gyro, accel, gyro_bias, accel_bias)
