"""LiDAR sweeps registered twice: odometry on the raw sweeps, then again de-skewed and without
their moving points.

The first odometry (scan-to-map VGICP, :class:`~rig.lidar_odometry.SweepOdometry`) registers
each raw sweep, its pose stamped when it holds (:func:`~rig.lidar_odometry.sweep_information`).
A sweep is de-skewed once the next one's pose is known, its moving points are found once the
sweeps it is compared with are in (:func:`~rig.dynamic_points.label_dynamic`), and its static
points are registered again by a second odometry that never sees a skewed sweep or a moving
point. The fallback mapper integrates the sweeps into its mesh at the second poses; the
calibration's LiDAR map merges their points.

The second registration is what holds a hand-held rig's poses: on the virtual office (seeds 0-3,
at the 20 frames the calibration uses, positions after a rigid alignment) the first odometry is
8.4-10.6 mm from the truth on average and up to 26 mm, the second 1.2-1.6 mm and up to 3 mm.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable, Iterator
from dataclasses import dataclass, field

import numpy as np

from rig.deskew import deskewed_points
from rig.dynamic_points import DEFAULT_DYNAMIC, DynamicConfig, label_dynamic
from rig.lidar_odometry import SweepOdometry, nearest_rotation, usable_sweep, voxel_for_ranges
from rig.messages import Scan
from rig.trajectory import Trajectory
from rig.transforms import invert, transform_points


@dataclass(frozen=True)
class SweepSettings:
    """Settings of the registration.

    Attributes:
        voxel_size_m: the odometry's voxel size; None picks it from the first sweep's ranges
            (:func:`~rig.lidar_odometry.voxel_for_ranges`).
        min_range_m, max_range_m: points outside are ignored.
        dynamic: the see-through test that finds moving points (None: off, and the sweeps are
            registered once).
        max_points_per_sweep: larger sweeps are thinned (:func:`~rig.lidar_odometry.thinned`)
            before anything else: every step costs in proportion to the points, and a 64-beam
            sweep has 4 to 5 times more than its registration and see-through test need. It costs
            the fallback mapper's mesh detail: on 78 sweeps of the virtual street with the
            HDL-64E's 125k points, the mapper takes 4.6 / 7.9 / 11.5 s with 32k / 64k / all
            points, ATE 0.93 / 0.83 / 0.78 cm, and 56 / 69 / 72 % of the mesh lies within 5 cm of
            the truth (85–88 % within 10 cm with any).
    """

    voxel_size_m: float | None = None
    min_range_m: float = 0.2
    max_range_m: float = 60.0
    dynamic: DynamicConfig | None = DEFAULT_DYNAMIC
    max_points_per_sweep: int = 32_000


@dataclass(eq=False)
class RegisteredSweep:
    """One sweep, de-skewed and registered.

    Attributes:
        t_ns: when its poses hold (host clock).
        pose: ``T_world_sensor`` ``(4, 4)`` of the second registration (the first's when the
            see-through test is off); world: the first sweep's LiDAR frame.
        points: ``(N, 3)`` its de-skewed points in the sensor frame at ``t_ns``.
        point_t_ns: ``(N,)`` int64 when each was measured (host clock).
        dynamic: ``(N,)`` which of them are moving.
    """

    t_ns: int
    pose: np.ndarray
    points: np.ndarray
    point_t_ns: np.ndarray
    dynamic: np.ndarray


@dataclass
class RegistrationLog:
    """Per sweep the first odometry registered: its stamp (ns), pose, smallest translation
    information and its direction (sensor frame); the voxel size chosen, the first usable sweep's
    ranges ``(N,)`` (m), the first odometry and the second (None until a sweep is registered
    again)."""

    voxel_m: float = 0.0
    first_ranges: np.ndarray = field(default_factory=lambda: np.zeros(0))
    odometry: SweepOdometry | None = None
    static_odometry: SweepOdometry | None = None
    t_ns: list[int] = field(default_factory=list)
    poses: list[np.ndarray] = field(default_factory=list)
    weakest_information: list[float] = field(default_factory=list)
    weakest_direction: list[np.ndarray] = field(default_factory=list)


def registered_sweeps(
    scans: Iterable[Scan],
    settings: SweepSettings,
    log: RegistrationLog,
    progress: Callable[[int], None] | None = None,
) -> Iterator[RegisteredSweep]:
    """The usable ``scans`` (in time order), each registered twice (see the module's docstring),
    recording the first registration in ``log``; ``progress`` is called with each scan's index as
    the first odometry takes it."""
    point_times: dict[int, np.ndarray] = {}  # of the sweeps de-skewed and not yet out
    staged = _deskewed_sweeps(scans, settings, log, progress, point_times)
    for index, view, dynamic in label_dynamic(staged, settings.dynamic):
        pose = view.T_world_sensor
        sensor = transform_points(invert(pose), view.points_world)
        if settings.dynamic is not None:
            static = sensor[~dynamic]
            if log.static_odometry is None:
                log.static_odometry = SweepOdometry(log.voxel_m, settings.max_range_m, settings.min_range_m)
            pose = log.static_odometry.register_rigid(static if len(static) >= 100 else sensor)
        yield RegisteredSweep(log.t_ns[index], pose, sensor, point_times.pop(index), dynamic)


def _deskewed_sweeps(
    scans: Iterable[Scan],
    settings: SweepSettings,
    log: RegistrationLog,
    progress: Callable[[int], None] | None,
    point_times: dict[int, np.ndarray],
) -> Iterator[tuple[float, np.ndarray, np.ndarray]]:
    """Register each usable scan (recording it in ``log``) and yield the one before it de-skewed:
    ``(t_s, points (N, 3) in the sensor frame, T_world_sensor)``; the i-th yielded sweep's point
    times go into ``point_times[i]``."""
    pending: tuple[np.ndarray, np.ndarray] | None = None  # the last scan's points and their times (ns)
    t_ns, poses = log.t_ns, log.poses

    def deskew_pending(pose_index: int) -> tuple[float, np.ndarray, np.ndarray]:
        recent = extended_at_both_ends(np.array(t_ns[-3:], dtype=np.int64), np.stack(poses[-3:]))
        points, point_t_ns = pending
        point_times[len(poses) + pose_index] = point_t_ns
        pose = poses[pose_index]
        return (
            t_ns[pose_index] * 1e-9,
            transform_points(invert(pose), deskewed_points(points, point_t_ns, recent)),
            pose,
        )

    for index, scan in enumerate(scans):
        sweep = usable_sweep(
            scan.points,
            scan.point_time_s,
            settings.max_points_per_sweep,
            settings.min_range_m,
            settings.max_range_m,
        )
        if sweep is None:
            continue
        points, times, ranges = sweep
        if log.odometry is None:
            voxel = settings.voxel_size_m
            log.voxel_m = voxel if voxel is not None else voxel_for_ranges(ranges)
            log.first_ranges = ranges
            log.odometry = SweepOdometry(log.voxel_m, settings.max_range_m, settings.min_range_m)
        pose, information = log.odometry.register(points, times)
        t_ns.append(int(scan.t_host) + round(information.held_s * 1e9))
        poses.append(pose)
        log.weakest_information.append(float(information.translation_information[0]))
        log.weakest_direction.append(information.weakest_direction)
        if pending is not None:
            yield deskew_pending(-2)
        pending = (points, int(scan.t_host) + np.round(times * 1e9).astype(np.int64))
        if progress is not None:
            progress(index)
    if len(poses) >= 2:
        yield deskew_pending(-1)


def extended_at_both_ends(t_ns: np.ndarray, poses: np.ndarray) -> Trajectory:
    """The trajectory of poses ``(K, 4, 4)`` at ``t_ns`` ``(K,)`` (K ≥ 2) with one more pose at each
    end, the motion of the end pair repeated: the first and last sweeps reach beyond the poses
    around them, and holding the end pose there left them half de-skewed (at 3 m/s the second
    registration's first step came out 7 cm short, as its map began with that sweep)."""
    before = nearest_rotation(poses[0] @ invert(poses[1]) @ poses[0])
    after = nearest_rotation(poses[-1] @ invert(poses[-2]) @ poses[-1])
    times = np.concatenate([[2 * t_ns[0] - t_ns[1]], t_ns, [2 * t_ns[-1] - t_ns[-2]]])
    return Trajectory.from_poses(times.astype(np.int64), np.concatenate([[before], poses, [after]]))
