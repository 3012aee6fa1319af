"""Each keyframe's LiDAR points: the scans between its neighbouring keyframes, deskewed by the
trajectory, without the points of moving objects, moved into its camera frame and kept where they
project into the image; and, apart, the points of moving objects that the sweeps taken with its
image hold (training masks their pixels out of the photometric loss).

Returns of a vehicle the see-through test misses, kept as static depth, pull triangles into a ghost
of its path. The test grows its mask within each sweep (:func:`~rig.dynamic_points.grown`: the
lower half of a car, where the range image's 3 x 3 minimum finds the nearer road), and a static
point is also dropped where its pixel lies within the moving mask
(:func:`~slam_bridge.depth_image.moving_pixel_mask`) of the moving points of its own sweep: the
missed returns of a vehicle lie beside the found ones of the same sweep. (The moving points of
all the sweeps of a keyframe's window would mask a vehicle's whole trail: on the 20 s street,
whose keyframes lie 0.5 s apart, 13 % of the static points instead of 2.9 %, and the mesh the
cameras see lost 0.015 F.)

A vehicle that the top of the LiDAR's field cuts (a lorry beside a car's roof LiDAR, whose top beam
rises 2°) goes on above its highest returns where no beam reaches: its moving points at the top of
the field are kept apart too (:func:`at_field_top`), and the mask reaches up from them."""

from __future__ import annotations

from collections.abc import Callable, Iterable, Iterator
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from rig.calibration import Calibration
from rig.camera import CameraModel
from rig.deskew import deskewed_sweep
from rig.dynamic_points import DEFAULT_DYNAMIC, DynamicConfig, SweepView, label_dynamic
from rig.messages import Scan
from rig.trajectory import Trajectory
from rig.transforms import invert, transform_points
from slam_bridge.depth_image import moving_pixel_mask
from slam_bridge.keyframe_selection import lidar_clock
from slam_bridge.scene import LIDAR_DIR, MOVING_DIR, MOVING_TOP_DIR, Keyframe

#: Points nearer than this along the camera's z are never depth (as in the z-buffer).
NEAR_M = 0.05
#: A keyframe's moving points come from the sweeps stamped within this of its image (half a sweep
#: of a 10 Hz LiDAR): a vehicle has not moved far from where the image shows it.
MOVING_WINDOW_S = 0.05
#: A sweep's field ends at the elevation of its FIELD_TOP_RANK-th highest return (a few stray returns
#: above the top beam do not lift it), and a point within FIELD_TOP_MARGIN_DEG below that (two or
#: three beam spacings of a 64-beam spinning LiDAR's upper block) is at the top of the field.
FIELD_TOP_RANK = 20
FIELD_TOP_MARGIN_DEG = 1.0


@dataclass(frozen=True)
class KeyframePoints:
    """Per keyframe (in time order), camera-frame points ``(N, 3)`` float32 in its image: the static
    ones of every scan in its window (less those beside the moving ones of the same scan,
    :func:`off_moving_pixels`), the moving ones of the sweeps taken with its image, and those of
    them at the top of the LiDAR's field (:func:`at_field_top`)."""

    static: list[np.ndarray]
    moving: list[np.ndarray]
    moving_at_top: list[np.ndarray]


def at_field_top(view: SweepView) -> np.ndarray:
    """``(N,)`` bool: the sweep's points within :data:`FIELD_TOP_MARGIN_DEG` of elevation (in the
    sensor's frame, z up) below the top of its field (:data:`FIELD_TOP_RANK`)."""
    sensor = transform_points(invert(view.T_world_sensor), view.points_world)
    elevation = np.degrees(np.arctan2(sensor[:, 2], np.hypot(sensor[:, 0], sensor[:, 1])))
    if len(elevation) < FIELD_TOP_RANK:
        return np.zeros(len(elevation), dtype=bool)
    top = np.partition(elevation, -FIELD_TOP_RANK)[-FIELD_TOP_RANK]
    return elevation >= top - FIELD_TOP_MARGIN_DEG


def keyframe_windows(t_ns: np.ndarray, interval_s: float) -> tuple[np.ndarray, np.ndarray]:
    """The time window ``[lo, hi]`` ``(K,)`` each of keyframes at increasing stamps ``(K,)``: from the
    previous keyframe to the next one (``interval_s`` before the first and after the last)."""
    t_ns = np.asarray(t_ns, dtype=np.int64)
    margin = int(interval_s * 1e9)
    lo = np.concatenate([[t_ns[0] - margin], t_ns[:-1]])
    hi = np.concatenate([t_ns[1:], [t_ns[-1] + margin]])
    return lo, hi


def in_view(points_cam: np.ndarray, camera: CameraModel) -> np.ndarray:
    """Camera-frame points ``(N, 3)`` beyond :data:`NEAR_M` that project into the image ``(M, 3)`` float32."""
    front = points_cam[points_cam[:, 2] > NEAR_M]
    return front[camera.in_image(camera.project(front))].astype(np.float32)


def keyframe_lidar(
    scans: Iterable[Scan],
    trajectory: Trajectory,
    calibration: Calibration,
    keyframes: list[Keyframe],
    camera: CameraModel,
    interval_s: float,
    dynamic: DynamicConfig | None = DEFAULT_DYNAMIC,
) -> KeyframePoints:
    """Per keyframe (in time order), the points in its camera frame of the scans stamped within its
    :func:`keyframe_windows` (on the camera clock), deskewed with the LiDAR ``trajectory`` (host
    clock) and seen by ``camera``, without the points of moving objects
    (:func:`~rig.dynamic_points.label_dynamic` with ``dynamic``; None keeps them) nor the static
    points of the same scan beside them in the image (:func:`off_moving_pixels`); the moving points
    are kept apart for the sweeps within :data:`MOVING_WINDOW_S` of the keyframe. Scans are
    streamed; each is deskewed once."""
    stamps_ns = np.array([k.t_ns for k in keyframes])
    lo, hi = keyframe_windows(stamps_ns, interval_s)
    lo, hi = lidar_clock(lo, calibration), lidar_clock(hi, calibration)
    image_t = lidar_clock(stamps_ns, calibration)
    T_cam_world = invert(np.stack([k.T_world_cam for k in keyframes]))
    chunks: list[list[np.ndarray]] = [[] for _ in keyframes]
    moving_chunks: list[list[np.ndarray]] = [[] for _ in keyframes]
    top_chunks: list[list[np.ndarray]] = [[] for _ in keyframes]
    stamps: list[int] = []  # each sweep's host stamp, by index

    def sweeps() -> Iterator[tuple[float, np.ndarray, np.ndarray]]:
        for scan in scans:
            wanted = np.searchsorted(hi, scan.t_host) < np.searchsorted(lo, scan.t_host, side="right")
            if not wanted and dynamic is None:
                continue  # no keyframe wants it, and no other sweep compares with it
            stamps.append(int(scan.t_host))
            yield deskewed_sweep(scan.points, scan.point_times_ns(host=True), int(scan.t_host), trajectory)

    for index, view, moving in label_dynamic(sweeps(), dynamic):
        t_host = stamps[index]
        first, stop = np.searchsorted(hi, t_host), np.searchsorted(lo, t_host, side="right")
        moving_at_top = moving & at_field_top(view) if moving.any() else moving
        for n in range(first, stop):
            in_camera = transform_points(T_cam_world[n], view.points_world)
            static = in_view(in_camera[~moving], camera)
            if moving.any():
                moving_in_view = in_view(in_camera[moving], camera)
                static = off_moving_pixels(static, moving_in_view, camera)
                if abs(t_host - image_t[n]) <= MOVING_WINDOW_S * 1e9:
                    moving_chunks[n].append(moving_in_view)
                    top_chunks[n].append(in_view(in_camera[moving_at_top], camera))
            chunks[n].append(static)

    def joined(parts: list[list[np.ndarray]]) -> list[np.ndarray]:
        return [np.concatenate(c) if c else np.zeros((0, 3), np.float32) for c in parts]

    return KeyframePoints(joined(chunks), joined(moving_chunks), joined(top_chunks))


def off_moving_pixels(static: np.ndarray, moving: np.ndarray, camera: CameraModel) -> np.ndarray:
    """The camera-frame points ``static`` ``(N, 3)`` (in the image) whose pixel lies outside the
    :func:`~slam_bridge.depth_image.moving_pixel_mask` of the points ``moving`` ``(M, 3)``."""
    if not len(moving) or not len(static):
        return static
    mask = moving_pixel_mask(moving, camera)
    pixels = np.round(camera.project(static.astype(np.float64))).astype(np.int64)
    cols = pixels[:, 0].clip(0, camera.width - 1)
    rows = pixels[:, 1].clip(0, camera.height - 1)
    return static[~mask[rows, cols]]


def write_keyframe_lidar(
    out: Path, keyframes: list[Keyframe], points: KeyframePoints, done: Callable[[], None]
) -> None:
    """Save each keyframe's static points ``(N, 3)`` float32 as ``out/lidar/NAME.npy``, its moving
    ones, where it has any, as ``out/moving/NAME.npy`` and those at the top of the LiDAR's field as
    ``out/moving_top/NAME.npy``; ``done()`` after each keyframe."""
    (out / LIDAR_DIR).mkdir(parents=True, exist_ok=True)
    rows = zip(keyframes, points.static, points.moving, points.moving_at_top, strict=True)
    for keyframe, static, moving, moving_at_top in rows:
        np.save(out / LIDAR_DIR / f"{keyframe.name}.npy", static)
        for folder, part in ((MOVING_DIR, moving), (MOVING_TOP_DIR, moving_at_top)):
            if len(part):
                (out / folder).mkdir(exist_ok=True)
                np.save(out / folder / f"{keyframe.name}.npy", part)
        done()
