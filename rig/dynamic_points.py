"""Points of moving objects in LiDAR sweeps: points that other sweeps see through.

A static surface blocks every later and earlier ray towards it; where a vehicle stood, sweeps
taken a moment before or after see past the spot to what is behind. So each sweep's points are
compared with the range images of sweeps some fractions of a second to seconds away (at their
own poses): a point is *seen through* by a sweep whose measured range in its direction — the
smallest in a 3 × 3 neighbourhood of bins, so that edges and grazing ground do not count — is
longer than the point's range by a margin. A point seen through often enough is dynamic.

The minimum misses the lower part of a vehicle: below its points the next beam down meets the
road, nearer than a point of the vehicle's lower half plus the margin (on the virtual street, 43 %
of the returns of a car crossing 20–28 m ahead). So the points of the same sweep near a dynamic
one join it, unless they lie on the ground (:func:`grown`).

This is the visibility test of range-image map cleaning (Removert, Kim & Kim, IROS 2020) on
neighbouring sweeps instead of a finished map; no maintained library does it on raw sweeps, so
the few vectorised lines are here.
"""

from __future__ import annotations

from collections.abc import Iterable, Iterator
from dataclasses import dataclass

import numpy as np
from scipy.ndimage import minimum_filter
from scipy.spatial import cKDTree

from rig.cpu_threads import cpu_threads
from rig.transforms import invert, transform_points


@dataclass(frozen=True)
class DynamicConfig:
    """Settings of the see-through test.

    Attributes:
        offsets_s: how far before and after a sweep (s) the sweeps it is compared with lie.
        azimuth_step_deg, elevation_step_deg: bin size of the range images; with the 3 × 3
            minimum, elevation bins as wide as the beam spacing put a lower beam in every window,
            so that ground seen at grazing angles is never "seen through".
        margin_m, margin_relative: a point is seen through where the image's range exceeds its
            own by ``max(margin_m, margin_relative * range)``.
        min_votes: sweeps that must see through a point (fewer if fewer were compared).
        grow_m, grow_support: a point of a sweep whose neighbours within ``grow_m`` are at
            least ``grow_support`` (a share above 0) dynamic is dynamic too, unless on the ground
            (0 m: no growth).
        ground_cell_m, ground_band_m: a point is on the ground where it lies less than
            ``ground_band_m`` above the lowest point of the sweep in its ``ground_cell_m`` cell of the
            sensor's x-y plane or the eight around it. The sensor's z axis must point roughly up
            (ROS REP 103; KITTI, the virtual rig); vehicles' bodies ride 0.2-0.3 m above the road.
    """

    offsets_s: tuple[float, ...] = (0.5, 1.0, 2.0)
    azimuth_step_deg: float = 0.5
    elevation_step_deg: float = 1.0
    margin_m: float = 0.4
    margin_relative: float = 0.04
    min_votes: int = 2
    grow_m: float = 0.8
    grow_support: float = 0.1
    ground_cell_m: float = 1.0
    ground_band_m: float = 0.25


#: The settings the mapper and the scene builder use unless told otherwise.
DEFAULT_DYNAMIC = DynamicConfig()


@dataclass
class SweepView:
    """One sweep as the see-through test needs it.

    Attributes:
        t_s: the sweep's time (s).
        T_world_sensor: ``(4, 4)`` its pose.
        points_world: ``(N, 3)`` its de-skewed points in the world frame.
        ranges: ``(R, C)`` float32 conservative range image (neighbourhood minimum; inf where empty;
            empty when no test runs).
    """

    t_s: float
    T_world_sensor: np.ndarray
    points_world: np.ndarray
    ranges: np.ndarray


def _bins(directions: np.ndarray, config: DynamicConfig) -> tuple[np.ndarray, tuple[int, int]]:
    """Flat index ``(N,)`` into the range image of unit sensor-frame ``directions`` ``(N, 3)``, and
    the image's shape (rows by elevation, columns by azimuth). Flat, because ``np.minimum.at``
    and gathers take one index array several times faster than a row and a column array."""
    shape = (int(np.ceil(180.0 / config.elevation_step_deg)), int(np.ceil(360.0 / config.azimuth_step_deg)))
    elevation = np.degrees(np.arcsin(np.clip(directions[:, 2], -1.0, 1.0)))
    azimuth = np.degrees(np.arctan2(directions[:, 1], directions[:, 0])) + 180.0
    row = np.clip(((elevation + 90.0) / config.elevation_step_deg).astype(np.int64), 0, shape[0] - 1)
    col = np.clip((azimuth / config.azimuth_step_deg).astype(np.int64), 0, shape[1] - 1)
    return row * shape[1] + col, shape


def sweep_view(
    t_s: float, points_sensor: np.ndarray, T_world_sensor: np.ndarray, config: DynamicConfig
) -> SweepView:
    """A :class:`SweepView` of de-skewed sensor-frame points ``(N, 3)`` at pose ``(4, 4)``."""
    ranges = np.linalg.norm(points_sensor, axis=1)
    pixel, shape = _bins(points_sensor / np.maximum(ranges, 1e-9)[:, None], config)
    image = np.full(shape[0] * shape[1], np.inf, dtype=np.float32)
    np.minimum.at(image, pixel, ranges.astype(np.float32))
    # Neighbourhood minimum; azimuth wraps round, elevation does not (its edges stay empty).
    image = minimum_filter(image.reshape(shape), size=3, mode=("constant", "wrap"), cval=np.inf)
    return SweepView(t_s, T_world_sensor, transform_points(T_world_sensor, points_sensor), image)


def seen_through(points_world: np.ndarray, other: SweepView, config: DynamicConfig) -> np.ndarray:
    """``(N,)`` bool: ``other`` sees past points ``(N, 3)`` (world) in their directions."""
    local = transform_points(invert(other.T_world_sensor), points_world)
    ranges = np.linalg.norm(local, axis=1)
    pixel, _ = _bins(local / np.maximum(ranges, 1e-9)[:, None], config)
    seen = other.ranges.reshape(-1)[pixel]
    margin = np.maximum(config.margin_m, config.margin_relative * ranges)
    return np.isfinite(seen) & (seen > ranges + margin)


def comparison_sweeps(index: int, times_s: np.ndarray, config: DynamicConfig) -> list[int]:
    """Indices of the sweeps (of times ``(S,)``) nearest ``offsets_s`` before and after sweep
    ``index``; offsets beyond the ends of ``times_s`` are skipped."""
    chosen = []
    for offset in config.offsets_s:
        for target in (times_s[index] - offset, times_s[index] + offset):
            if times_s[0] - 0.05 <= target <= times_s[-1] + 0.05:
                j = int(np.argmin(np.abs(times_s - target)))
                if j != index and j not in chosen:
                    chosen.append(j)
    return chosen


def on_ground(points_sensor: np.ndarray, config: DynamicConfig) -> np.ndarray:
    """``(N,)`` bool: the points ``(N, 3)`` of one sweep (sensor frame, z up) that lie within
    ``ground_band_m`` above the lowest point of their ``ground_cell_m`` cell or its neighbours."""
    cells = np.floor(points_sensor[:, :2] / config.ground_cell_m).astype(np.int64)
    cells -= cells.min(axis=0)
    lowest = np.full(tuple(cells.max(axis=0) + 1), np.inf)
    np.minimum.at(lowest, (cells[:, 0], cells[:, 1]), points_sensor[:, 2])
    lowest = minimum_filter(lowest, size=3, mode="constant", cval=np.inf)
    return points_sensor[:, 2] - lowest[cells[:, 0], cells[:, 1]] < config.ground_band_m


def grown(points_sensor: np.ndarray, seeds: np.ndarray, config: DynamicConfig) -> np.ndarray:
    """``(N,)`` bool: the ``seeds`` ``(N,)`` of one sweep's points ``(N, 3)`` (sensor frame) and the
    points not :func:`on_ground` of whose neighbours within ``grow_m`` at least ``grow_support``
    are seeds. A share, not a count: a lone seed on a wall must not take the hundreds of points
    around it that a LiDAR draws 3 m away, while a vehicle's seeds crowd its lower half."""
    if config.grow_m <= 0 or not seeds.any():
        return seeds
    low = points_sensor[seeds].min(axis=0) - config.grow_m
    high = points_sensor[seeds].max(axis=0) + config.grow_m
    near = np.flatnonzero(~seeds & np.all((points_sensor >= low) & (points_sensor <= high), axis=1))
    near = near[~on_ground(points_sensor, config)[near]]
    around = np.all((points_sensor >= low - config.grow_m) & (points_sensor <= high + config.grow_m), axis=1)

    def neighbours(of: np.ndarray, at: np.ndarray) -> np.ndarray:
        """How many of the points ``of`` lie within ``grow_m`` of each of the points ``at``."""
        tree = cKDTree(points_sensor[of])
        # Exact counts on any number of threads (a KITTI-size drive's 4.6 -> 3.8 s on 2); one in
        # the mapper that runs beside a calibration.
        return tree.query_ball_point(
            points_sensor[at], config.grow_m, return_length=True, workers=cpu_threads()
        )

    # Only points with a seed within reach can join (the room's sweeps: a few stray seeds, and
    # counting all their thousands of neighbours took most of the time).
    support = neighbours(seeds, near)
    reached = support > 0
    near, support = near[reached], support[reached]
    out = seeds.copy()
    out[near[support >= config.grow_support * neighbours(around, near)]] = True
    return out


def dynamic_mask(sweep: SweepView, others: list[SweepView], config: DynamicConfig) -> np.ndarray:
    """``(N,)`` bool: points of ``sweep`` that at least ``min_votes`` of ``others`` see through
    (all of them when fewer were given), :func:`grown` in the sweep."""
    if not others:
        return np.zeros(len(sweep.points_world), dtype=bool)
    votes = sum(seen_through(sweep.points_world, other, config).astype(np.int32) for other in others)
    points_sensor = transform_points(invert(sweep.T_world_sensor), sweep.points_world)
    return grown(points_sensor, votes >= min(config.min_votes, len(others)), config)


def label_dynamic(
    sweeps: Iterable[tuple[float, np.ndarray, np.ndarray]], config: DynamicConfig | None
) -> Iterator[tuple[int, SweepView, np.ndarray]]:
    """Each sweep ``(t_s, points_sensor (N, 3) de-skewed, T_world_sensor (4, 4))``, in time order,
    as its index in the input, a :class:`SweepView` and its ``(N,)`` dynamic mask (all False when
    ``config`` is None).

    A sweep comes out once the sweeps ``max(offsets_s)`` after it are in (and at the end of the
    input), and only the sweeps still needed for comparison are held, so memory stays bounded.
    """
    if config is None:  # no range images, no waiting
        for index, (t_s, points, T_world_sensor) in enumerate(sweeps):
            view = SweepView(t_s, T_world_sensor, transform_points(T_world_sensor, points), np.empty((0, 0)))
            yield index, view, np.zeros(len(points), dtype=bool)
        return
    wait_s = max(config.offsets_s)
    views: list[SweepView] = []
    emitted = 0  # views[:emitted] are out and kept only for comparison
    dropped = 0  # views dropped from the front of ``views`` so far
    iterator = iter(sweeps)
    while True:
        item = next(iterator, None)
        if item is not None:
            views.append(sweep_view(*item, config))
        times = np.array([v.t_s for v in views])
        while emitted < len(views) and (item is None or times[emitted] + wait_s <= times[-1]):
            view = views[emitted]
            others = [views[j] for j in comparison_sweeps(emitted, times, config)]
            yield dropped + emitted, view, dynamic_mask(view, others, config)
            emitted += 1
        if item is None:
            return
        if emitted < len(views):
            keep_from = int(np.searchsorted(times, times[emitted] - wait_s - 0.05))
            views, emitted, dropped = views[keep_from:], emitted - keep_from, dropped + keep_from
