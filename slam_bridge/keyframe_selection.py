"""Choosing keyframes among a session's camera frames, and their camera poses on the LiDAR trajectory."""

from __future__ import annotations

import numpy as np

from rig.calibration import Calibration
from rig.errors import InputError
from rig.session import Recording
from rig.trajectory import Trajectory
from rig.transforms import distance_and_angle, invert
from slam_bridge.scene import Keyframe


def lidar_clock(t_cam_ns: np.ndarray, calibration: Calibration) -> np.ndarray:
    """Camera-clock stamps ``(N,)`` int64 expressed on the LiDAR clock (minus ``time_offset_s``)."""
    return np.asarray(t_cam_ns, dtype=np.int64) - round(calibration.time_offset_s * 1e9)


def frame_stamps(reader: Recording, topic: str) -> np.ndarray:
    """Times ``(N,)`` int64 (``t_host``) of the frames on ``topic`` in file order, images not decoded."""
    stamps = reader.stamps(topic)
    if stamps.size == 0:
        raise InputError(f"no images on {topic}", path=reader.path)
    return stamps


#: The keyframe spacing when none is given: one per this many seconds (the paper's ~0.5 s) ...
DEFAULT_INTERVAL_S = 0.5
#: ... or closer, so that a short recording still gives this many keyframes (a 7.8 s drive 39
#: instead of 16, every eighth of them a test view) ...
MIN_KEYFRAMES = 40
#: ... but never closer than this (a 3 s recording gives 15 or 16, not one per frame).
MIN_INTERVAL_S = 0.2


def covered_frames(frame_t_ns: np.ndarray, trajectory: Trajectory, calibration: Calibration) -> np.ndarray:
    """Indices ``(M,)`` of the camera frames (stamps ``(N,)``) the trajectory covers; an error when
    it covers none."""
    covered = np.flatnonzero(trajectory.covers(lidar_clock(frame_t_ns, calibration)))
    if covered.size == 0:
        raise InputError(
            "the trajectory covers none of the camera frames (check time_offset_s and the SLAM folder)",
            field="trajectory",
        )
    return covered


def default_interval(frame_t_ns: np.ndarray, trajectory: Trajectory, calibration: Calibration) -> float:
    """Seconds between keyframes when none is given: :data:`DEFAULT_INTERVAL_S`, or the span of the
    covered frames (stamps ``(N,)``) over the :data:`MIN_KEYFRAMES` - 1 gaps between keyframes when
    that is shorter, down to :data:`MIN_INTERVAL_S`; below 0.5 s a whole number of frame periods
    (0.21 s of 30 Hz frames would take every seventh, 0.233 s apart)."""
    covered = frame_t_ns[covered_frames(frame_t_ns, trajectory, calibration)]
    span_s = float(covered[-1] - covered[0]) * 1e-9
    interval = float(np.clip(span_s / (MIN_KEYFRAMES - 1), MIN_INTERVAL_S, DEFAULT_INTERVAL_S))
    if interval == DEFAULT_INTERVAL_S or len(covered) < 2:
        return interval
    period = float(np.median(np.diff(covered))) * 1e-9
    return max(period, np.floor(interval / period + 1e-3) * period)


def camera_poses(trajectory: Trajectory, calibration: Calibration, t_cam_ns: np.ndarray) -> np.ndarray:
    """``T_world_cam`` ``(N, 4, 4)`` at camera stamps ``(N,)``: the LiDAR trajectory at the LiDAR
    time of each frame composed with ``T_lidar_cam``."""
    return trajectory.interpolate(lidar_clock(t_cam_ns, calibration)) @ invert(calibration.T_cam_lidar)


def select_keyframes(
    frame_t_ns: np.ndarray,
    trajectory: Trajectory,
    calibration: Calibration,
    interval_s: float,
    min_motion: tuple[float, float] | None = None,
    max_travel_m: float = 0.0,
) -> np.ndarray:
    """Indices of camera frames to keep, only where the trajectory covers them: one per
    ``interval_s``, and sooner where the camera has moved ``max_travel_m`` (> 0) since the last
    keyframe; or — with ``min_motion = (metres, degrees)`` — the next frame whose camera has moved
    or turned at least that much since the last keyframe."""
    covered = covered_frames(frame_t_ns, trajectory, calibration)
    by_motion = min_motion is not None
    poses = camera_poses(trajectory, calibration, frame_t_ns[covered]) if by_motion or max_travel_m else None
    chosen = [0]
    for j in range(1, len(covered)):
        moved, angle = (0.0, 0.0) if poses is None else distance_and_angle(poses[j], poses[chosen[-1]])
        if by_motion:
            keep = moved >= min_motion[0] or np.degrees(angle) >= min_motion[1]
        else:
            elapsed_s = (frame_t_ns[covered[j]] - frame_t_ns[covered[chosen[-1]]]) * 1e-9
            keep = elapsed_s >= interval_s - 1e-6 or 0 < max_travel_m <= moved + 1e-6
        if keep:
            chosen.append(j)
    return covered[np.asarray(chosen)]


def describe_spacing(
    t_ns: np.ndarray, interval_s: float, min_motion: tuple[float, float] | None, max_travel_m: float
) -> str:
    """How the keyframes at stamps ``(K,)`` were spaced, for a log line: "one per 0.5 s or 1 m
    travelled (12 sooner by distance)"."""
    if min_motion is not None:
        return f"one per {min_motion[0]:g} m or {min_motion[1]:g} deg of motion"
    line = f"one per {interval_s:.3g} s"
    if not max_travel_m:
        return line
    sooner = int(np.sum(np.diff(np.asarray(t_ns, dtype=np.int64)) * 1e-9 < interval_s - 1e-6))
    return f"{line} or {max_travel_m:g} m travelled ({sooner} sooner by distance)"


def make_keyframes(t_ns: np.ndarray, poses: np.ndarray, test_every: int) -> list[Keyframe]:
    """Keyframes ``kf_0000, kf_0001, …`` at stamps ``(K,)`` with poses ``T_world_cam`` ``(K, 4, 4)``;
    every ``test_every``-th one (0: none) is held out for testing."""
    return [
        Keyframe(
            f"kf_{n:04d}",
            int(t),
            T_world_cam,
            "test" if test_every and n % test_every == test_every - 1 else "train",
        )
        for n, (t, T_world_cam) in enumerate(zip(t_ns, poses, strict=True))
    ]
