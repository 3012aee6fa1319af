"""Targetless extrinsic from a recording: the LiDAR map must look the same in every camera frame.

A map point seen by several frames has one colour; placed in the images with the wrong
``T_cam_lidar`` (and the LiDAR's own poses from odometry), it lands on different things in each
and its grey levels disagree. The cost is the spread of each point's grey level over the frames
that see it, relative to the spread between points (so it cannot be lowered by moving every point
onto one flat wall). Unlike edges or mutual information in one frame, this needs nothing from the
LiDAR but geometry, and every frame's parallax constrains the translation.

Coarse to fine over image blurs (:data:`BLUR_STAGES`), a derivative-free 6-DoF search per blur,
each seeing the map points visible (z-buffer of the map and the frame's moving things) in at least
:data:`MIN_VIEWS` frames at its start (the blurred stages a share of them, :data:`SAMPLE_BLUR`);
then a scan along each axis for a deeper minimum (:func:`_out_of_the_valley`) and a descent along
the free translations, each step scored on the points visible where it lands
(:func:`_descend_translations`). A straight drive leaves two axes unobserved; they are kept from
the guess (:func:`_straight_travel`). Where the time offset that placed the frames may be off,
it is a seventh coefficient of every search: each frame is placed again along the map's
trajectory, its points moved by the change of its pose (:meth:`_Observations.transforms`).
Grey levels are standardised per frame (auto-exposure), and the worst :data:`TRIM` of the points
(specular surfaces, points hidden by something the LiDAR missed) are left out of the mean.
Uncertainty: the larger of a jackknife over stretches of frames and the region where the cost
stays within :data:`COST_TOLERANCE` of its lowest (:func:`_spread`), and a check that the result
is a clear minimum along every free translation (:func:`_flat_translations`), which the
jackknife cannot see.
"""

from __future__ import annotations

import itertools
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from types import ModuleType
from typing import TYPE_CHECKING

import cv2
import numpy as np
from scipy.optimize import minimize
from threadpoolctl import ThreadpoolController

from calib.intervals import NORMAL_95, jackknife_interval_95
from calib.lidar_map import LidarMap
from calib.photo_kernel import photo_extension
from calib.targetless import ExtrinsicResult, apply_increment, working_image, working_pixels
from rig.camera import CameraModel
from rig.errors import InputError
from rig.trajectory import Trajectory
from rig.transforms import invert, transform_points

if TYPE_CHECKING:
    import torch

#: Gaussian blurs (pixels at the working width, 960) of the coarse-to-fine stages: the first
#: ones let a guess 10° off find the way (10° is 170 px at 960 px for a 90° field of view).
BLUR_STAGES = (32.0, 16.0, 8.0, 4.0, 2.0, 1.0)
#: A point counts where at least this many frames see it.
MIN_VIEWS = 3
#: The worst fraction of points (largest spread over frames) left out of the cost.
TRIM = 0.1
#: A point is hidden when a map point within this window (working pixels, odd) is more than
#: DEPTH_TOLERANCE = (relative, metres) in front of it.
OCCLUSION_PX = 7
DEPTH_TOLERANCE = (0.03, 0.03)
#: Powell's tolerance per stage (degrees and decimetres): coarse stages only need to hand over.
XTOL = (3e-2, 1e-2, 1e-2, 1e-2, 3e-3, 1e-3)
#: A stage at a blur of s working pixels scores every (s / SAMPLE_BLUR)-th point (at least
#: MIN_POINTS of them): neighbouring points sample nearly the same grey level of a blurred image.
SAMPLE_BLUR = 4.0
#: How far from the guess the search may go (degrees and decimetres per axis): past the basin it
#: is meant for (10° / 30 cm), short of places where the points project somewhere else entirely
#: (unbounded, a 64-beam street's search ran 26-64 m away).
SEARCH_REACH = (15.0, 5.0)
#: A rig whose frames turn less than this (degrees) drives straight: the roll about its direction
#: of travel and the shift along it are kept from the guess (the virtual room's robot turns
#: 53°, the virtual street's car 0.7°). The travel must span MIN_TRAVEL_M to have a direction.
MIN_TURN_DEG = 10.0
MIN_TRAVEL_M = 0.5
#: The result must see at least this fraction of the points the guess sees (a search that ran
#: off to where the camera sees little of the map can look consistent).
MIN_SEEN_FRACTION = 0.7
#: A result is told apart from the points PROFILE_STEP_M away along each free translation only
#: when they cost at least MIN_RISE more (:func:`_flat_translations`). At the truth of the
#: virtual room's 10 s seeds 0-2 the smallest rise 10 cm away is 9.4 / 5.7 / 7.6 %; a 20 s room
#: run from the motion's guess ended 12.6 cm off along the robot's turning axis with 2.9 %, and
#: its jackknife said ±1.5 cm.
PROFILE_STEP_M = 0.1
MIN_RISE = 0.03
#: A step along a free translation whose plain rise is under REFIT_BELOW x MIN_RISE is scored
#: again with the rotation re-fitted to it (:func:`_refit_rotation`, to REFIT_XTOL_DEG); steeper
#: ones are left.
REFIT_BELOW = 4
REFIT_XTOL_DEG = 0.01
#: The scans along each axis (:func:`_out_of_the_valley`): blur, reach (degrees and decimetres)
#: and steps to each side.
VALLEY_BLUR = 4.0
VALLEY_REACH = 3.0
VALLEY_STEPS = 6
#: The last descent along the free translations on the points visible where each step lands
#: (:func:`_descend_translations`): its steps, metres.
DESCENT_STEPS_M = (0.1, 0.05, 0.025)
#: Finite-difference steps (degrees, decimetres, TIME_UNIT_S) and the stretches of frames of the jackknife:
#: at 0.05° / 5 mm the cost's curvature was mostly noise (a near-zero eigenvalue on the room).
STEP = (0.15, 0.15, 0.15)
JACKKNIFE_GROUPS = 5
MIN_FRAMES = 4
MIN_POINTS = 2000
#: OpenCV's remap addresses images and maps of fewer rows and columns than this.
REMAP_LIMIT = 32767
#: The cost's own error, relative: its minimum lies off the truth by about as far as the cost
#: rises by this fraction from it, in a direction every stretch of frames shares (so the
#: jackknife cannot see it). The smallest value (in steps of 0.1 %) whose 95 % interval holds
#: the truth in 90 % of each scene's trials over the virtual room's and office's seeds 0-19
#: (room 60 of 60, office 51 of 56; the jackknife alone 41 and 36). It was 0.7 % while the LiDAR
#: map's odometry placed the office's frames 8-11 mm off (``rig.sweep_registration``).
COST_TOLERANCE = 0.004
#: The time offset searched with the extrinsic, where it may be off: a time offset moves every
#: frame along its motion, which the cost sees (the virtual office's hand-held rig turns up to
#: 37°/s: at the true extrinsic 2.5 ms cost 1-4 % more, and the lowest lay on the true offset).
#: Its coefficient counts TIME_UNIT_S (1 is about 0.4° of the office's fastest turn, as the
#: rotation's coefficient counts degrees).
TIME_UNIT_S = 0.01
#: Verdict limits on the standard deviations: half of 0.5° / 5 cm (the 95 % interval is 2.78σ).
MAX_ROT_STD_DEG = 0.25
MAX_TRANS_STD_M = 0.025
METHOD = "targetless (photo-consistency of the LiDAR map over {} frames)"


@dataclass(eq=False)
class ConsistencyFrame:
    """One camera image ``(H, W[, 3])`` uint8, the LiDAR's pose ``T_world_lidar`` ``(4, 4)`` (the
    map's world) at the instant ``t_ns`` it was taken, and ``occluders`` ``(K, 3)``: world points
    of things that stood there then but are not in the map (moving vehicles), which hide the map
    points behind them in this image."""

    image: np.ndarray
    T_world_lidar: np.ndarray
    occluders: np.ndarray = field(default_factory=lambda: np.zeros((0, 3)))
    #: When it was taken, on the LiDAR's clock (ns): where the map's trajectory places it again
    #: when the time offset moves; None where that is unknown.
    t_ns: int | None = None


@dataclass(eq=False)
class _Parameters:
    """What the search moves: ``T_cam_lidar`` = ``T_init`` turned and moved by ``basis[:6] @ y``
    (:func:`~calib.targetless.apply_increment`; degrees and decimetres), and the time offset by
    ``basis[6] @ y`` (:data:`TIME_UNIT_S`). ``basis`` ``(7, k)`` has orthonormal columns, each a
    rotation, a translation or the time: all six axes, or fewer where the motion cannot observe
    some (:func:`_observable_basis`), and the time where the offset may be off by up to
    ``time_reach`` (units of :data:`TIME_UNIT_S`)."""

    T_init: np.ndarray
    basis: np.ndarray
    time_reach: float = 0.0

    def pose(self, y: np.ndarray) -> np.ndarray:
        """``T_cam_lidar`` ``(4, 4)`` at coefficients ``y`` ``(k,)``."""
        return apply_increment(self.basis[:6] @ y, self.T_init)

    def shift_s(self, y: np.ndarray) -> float:
        """How much larger (s) the time offset is at coefficients ``y`` ``(k,)``."""
        return float(self.basis[6] @ y) * TIME_UNIT_S

    def is_rotation(self) -> np.ndarray:
        """``(k,)`` bool: which columns turn."""
        return np.abs(self.basis[:3]).sum(axis=0) > 0

    def is_translation(self) -> np.ndarray:
        """``(k,)`` bool: which columns move."""
        return np.abs(self.basis[3:6]).sum(axis=0) > 0

    def per_column(self, rotation: float, translation: float, time: float) -> np.ndarray:
        """``(k,)``: ``rotation`` for the turning columns, ``translation`` for the moving ones,
        ``time`` for the time's."""
        return np.where(self.is_rotation(), rotation, np.where(self.is_translation(), translation, time))

    def bounds(self) -> list[tuple[float, float]]:
        """Powell's bounds on ``y``: :data:`SEARCH_REACH` along every column, ``time_reach``
        along the time's."""
        reach = self.per_column(*SEARCH_REACH, self.time_reach)
        return list(zip(-reach, reach, strict=True))


@dataclass(eq=False)
class _Timing:
    """When the frames were taken: their instants ``t_ns`` ``(F,)`` on the LiDAR clock at the
    time offset given, and the map's ``trajectory`` that places them."""

    trajectory: Trajectory
    t_ns: np.ndarray

    def poses(self, shift_s: float) -> np.ndarray:
        """``(F, 4, 4)`` the LiDAR's poses at the frames with the time offset ``shift_s`` larger
        (a camera stamp ``t`` is ``t - offset`` on the LiDAR clock)."""
        return self.trajectory.interpolate(self.t_ns - round(shift_s * 1e9), clamp=True)


class _Problem:
    """The frames' working images and the map in each frame's LiDAR coordinates; the compiled
    cost on ``threads`` threads."""

    def __init__(
        self,
        frames: Sequence[ConsistencyFrame],
        camera: CameraModel,
        world: np.ndarray,
        timing: _Timing | None = None,
        threads: int = 1,
    ) -> None:
        self.threads = threads
        prepared = [working_image(frame.image, camera) for frame in frames]
        self.grays = [gray.astype(np.float32) for gray, _ in prepared]
        self.K = prepared[0][1]
        self.height, self.width = self.grays[0].shape
        self.n_map = len(world)
        self.world = [np.vstack([world, f.occluders]) for f in frames]
        #: Where the frames are when the time offset moves (None: it stays), and how far it has.
        self.timing, self.shift_s = timing, 0.0
        self._poses_at: tuple[float, np.ndarray | None] = (np.nan, None)
        self._place(np.array([f.T_world_lidar for f in frames]))
        #: The images sampled now, stacked ``(F * height, width)``: one remap samples every frame.
        self.images = np.vstack(self.grays)
        if len(self.images) >= REMAP_LIMIT:  # 20 frames 320 wide: images taller than 5:1
            raise InputError(
                f"{len(frames)} frames of {self.width}x{self.height} working images stack to "
                f"{len(self.images)} rows; expected fewer than {REMAP_LIMIT}",
                field="image",
            )

    def _place(self, poses: np.ndarray) -> None:
        """Put the frames at the LiDAR poses ``T_world_lidar`` ``(F, 4, 4)``."""
        self.poses = poses
        #: Per frame ``(3, N + K_f)`` float32 in its LiDAR frame: the map's N points (they do not
        #: depend on the extrinsic), then the frame's K_f occluders (they hide, they are not scored).
        self.frame_points = [
            np.ascontiguousarray(transform_points(invert(pose), points).T, dtype=np.float32)
            for pose, points in zip(poses, self.world, strict=True)
        ]

    def at_shift(self, shift_s: float) -> None:
        """Put the frames where they were taken with the time offset ``shift_s`` larger than the
        one that placed them (:class:`_Timing`)."""
        if shift_s != self.shift_s:
            self._place(self.poses_at(shift_s))
            self.shift_s = shift_s

    def blur(self, sigma: float) -> None:
        """Sample blurred images from now on (``sigma`` at the working width)."""
        pixels = working_pixels(sigma, self.width)
        self.images = np.vstack([cv2.GaussianBlur(g, (0, 0), pixels) for g in self.grays])

    def visible(self, T: np.ndarray) -> np.ndarray:
        """``(F, N)`` mask of map points in view and in front in each frame with ``T_cam_lidar``
        ``T`` ``(4, 4)`` (z-buffer of the map and the frame's occluders)."""
        R, t = T[:3, :3].astype(np.float32), T[:3, 3, None].astype(np.float32)
        cameras = [R @ points + t for points in self.frame_points]
        extension = photo_extension()
        if extension is not None:
            return self.kernel_visible(extension, cameras)
        seen = np.zeros((len(cameras), self.n_map), dtype=bool)
        for k, camera in enumerate(cameras):
            shown = _shown_points(camera, self.K, self.width, self.height)
            seen[k, shown[shown < self.n_map]] = True
        return seen

    def kernel_visible(self, extension: ModuleType, cameras: list[np.ndarray]) -> np.ndarray:
        """:meth:`visible` of the frames' points in their cameras (each ``(3, N + K_f)`` float32) by
        the compiled ``extension`` (:mod:`calib.photo_kernel`) on :attr:`threads` threads: the same
        mask as :func:`_shown_points` gives. A 20-frame KITTI-size drive's call (120 000 map
        points, 960 x 290, the matrix products included) takes 72 ms in NumPy, 54 ms here on one
        thread and 41 ms on two."""
        (fx, _, cx), (_, fy, cy) = self.K[:2]
        seen = extension.shown_points(
            [_tensor(c, np.float32) for c in cameras], self.n_map,
            float(fx), float(fy), float(cx), float(cy), self.width, self.height, OCCLUSION_PX,
            1 + DEPTH_TOLERANCE[0], DEPTH_TOLERANCE[1], self.threads,
        )  # fmt: skip
        return seen.numpy()

    def observations(
        self,
        T: np.ndarray,
        frames: np.ndarray,
        stride: int = 1,
        shift_s: float = 0.0,
        seen: np.ndarray | None = None,
    ) -> _Observations:
        """The map points that at least :data:`MIN_VIEWS` of ``frames`` (indices) see with
        ``T_cam_lidar`` ``T`` and the time offset ``shift_s`` larger (:meth:`at_shift`), or by
        the mask ``seen`` ``(F, N)`` (:meth:`visible`) where given, one observation per (frame,
        point); every ``stride``-th of them (fewer while under :data:`MIN_POINTS` would remain)."""
        self.at_shift(shift_s)
        visible = (self.visible(T) if seen is None else seen)[frames]
        seen = np.flatnonzero(visible.sum(axis=0) >= MIN_VIEWS)
        scored = np.zeros(self.n_map, dtype=bool)
        scored[seen[:: max(1, min(stride, len(seen) // MIN_POINTS))]] = True
        visible &= scored
        # Row-major, so grouped by frame (np.nonzero's pairs, three times faster).
        rows, points = np.divmod(np.flatnonzero(visible), self.n_map)
        # The observed points' indices among themselves, in map order (np.unique's, without a sort).
        observed = visible.any(axis=0)
        compact = (np.cumsum(observed) - 1)[points]
        per_frame = np.split(points, np.searchsorted(rows, np.arange(1, len(frames))))
        # np.take along the axis: 5x faster than fancy indexing of the columns.
        xyz = np.hstack(
            [np.take(self.frame_points[f], p, axis=1) for f, p in zip(frames, per_frame, strict=True)]
        )
        sampled = _by_image_position(xyz, [len(p) for p in per_frame], T, self.K, self.width, self.height)
        return _Observations(
            xyz, rows, compact, int(observed.sum()), self.height, frames, self.poses, sampled, self.shift_s
        )

    def poses_at(self, shift_s: float) -> np.ndarray:
        """``(F, 4, 4)`` the frames' LiDAR poses with the time offset ``shift_s`` larger (the last
        one asked for is kept: a search moves the time along some of its directions only)."""
        if shift_s != self._poses_at[0]:
            self._poses_at = (shift_s, self.timing.poses(shift_s))
        return self._poses_at[1]

    def spreads(self, T: np.ndarray, obs: _Observations, shift_s: float = 0.0) -> tuple[np.ndarray, float]:
        """The grey-level variance over the frames that see it ``(n,)`` of each observed point that
        at least :data:`MIN_VIEWS` of them see in the image, and the variance of these points' mean
        grey levels, with ``T_cam_lidar`` ``T`` and the time offset ``shift_s`` larger (grey
        levels standardised per frame)."""
        extension = photo_extension()
        moves = obs.transforms(T, None if shift_s == obs.shift_s else self.poses_at(shift_s))
        sums = (
            self.point_sums(moves, obs)
            if extension is None
            else self.kernel_point_sums(extension, moves, obs)
        )
        total, total_square, count = sums
        good = count >= MIN_VIEWS
        point_mean = total[good] / count[good]
        point_square = total_square[good] / count[good]
        spread = np.maximum(point_square - point_mean**2, 0.0)
        return spread, float(np.var(point_mean)) if len(point_mean) else 0.0

    def point_sums(self, moves: np.ndarray, obs: _Observations) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Per observed point ``(n_points,)``: the sums of its grey levels standardised per frame
        and of their squares (float64), and how many of its observations fall inside their image
        (int64), each run of observations moved into the camera by its ``moves`` ``(R, 3, 4)``
        (:meth:`_Observations.transforms`). The specification of the compiled
        :meth:`kernel_point_sums`, and its stand-in."""
        # The search's inner loop (thousands of calls): float32 points, (3, m) for one matrix
        # product per frame, per-frame sums over contiguous runs instead of scattered bincounts,
        # and the few observations that fall outside their image zeroed instead of weighting all.
        camera = np.empty_like(obs.xyz)
        for move, start, length in zip(moves, obs.run_starts, obs.run_lengths, strict=True):
            run = slice(start, start + length)
            camera[:, run] = move[:, :3] @ obs.xyz[:, run] + move[:, 3, None]
        u, v, _, inside = _project(camera.T, self.K, self.width, self.height)
        # A point inside its frame samples only that frame's rows of the stack.
        values = _bilinear(self.images, u, v + obs.row_offset).astype(np.float64)
        outside = np.flatnonzero(~inside)
        values[outside] = 0.0
        # Standardised per frame: auto-exposure changes gain and offset between frames.
        missed = np.bincount(obs.run[outside], minlength=len(obs.run_lengths))
        n_frame = np.maximum(obs.run_lengths - missed, 1)
        mean = np.add.reduceat(values, obs.run_starts) / n_frame
        square = np.add.reduceat(values * values, obs.run_starts) / n_frame
        scale = 1 / np.sqrt(np.maximum(square - mean**2, 1e-6))
        values = (values - np.repeat(mean, obs.run_lengths)) * np.repeat(scale, obs.run_lengths)
        values[outside] = 0.0
        count = obs.point_counts - np.bincount(obs.point[outside], minlength=obs.n_points)
        total = np.bincount(obs.point, values, minlength=obs.n_points)
        return total, np.bincount(obs.point, values * values, minlength=obs.n_points), count

    def kernel_point_sums(
        self, extension: ModuleType, moves: np.ndarray, obs: _Observations
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """:meth:`point_sums` in one pass of the compiled ``extension`` (:mod:`calib.photo_kernel`)
        on :attr:`threads` threads. On one, for the 214 000 observations of a 20-frame room 4.4 ->
        2.3 ms, and 16 -> 2.4 ms while another process keeps a core busy (NumPy's matrix product
        waits on OpenBLAS's threads); sampled in ``obs.sampled``'s order (by where the points fall
        in their image) and the projection vectorised, the 320 000 of a 20-frame KITTI-size drive
        at 960 x 290 8.7 -> 5.3 ms (4.1-4.4 ms on two threads), with the same sums to the bit. Its
        bilinear samples are exact where OpenCV's are at 1/32 px, and its sums are added in
        another order: the sums agree to ~1e-3, the cost to ~1e-6 (relative)."""
        (fx, _, cx), (_, fy, cy) = self.K[:2]
        runs = (_tensor(r, np.int64) for r in (obs.run_starts, obs.run_lengths, obs.run_rows))
        sums = extension.point_sums(
            _tensor(self.images, np.float32), _tensor(obs.xyz_sampled, np.float32),
            _tensor(moves, np.float32), float(fx), float(fy), float(cx), float(cy), self.height, *runs,
            _tensor(obs.point, np.int64), _tensor(obs.sampled, np.int64), obs.n_points, self.threads,
        )  # fmt: skip
        return tuple(s.numpy() for s in sums)

    def cost(self, T: np.ndarray, obs: _Observations, shift_s: float = 0.0) -> float:
        """The photo-inconsistency of the observed points with ``T_cam_lidar`` ``T`` and the time
        offset ``shift_s`` larger: the mean of :meth:`spreads` over the points but the worst
        :data:`TRIM`, over the variance between points (so that moving every point onto one flat
        wall does not pay)."""
        spread, between = self.spreads(T, obs, shift_s)
        kept = int(len(spread) * (1 - TRIM))
        if kept < MIN_POINTS // 4:
            return 1e3
        return float(np.partition(spread, kept - 1)[:kept].mean()) / max(between, 1e-9)


class _Observations:
    """Flat (frame, point) observations, grouped by frame: the point in the frame's LiDAR
    coordinates ``xyz`` ``(3, M)`` float32, the position ``row`` ``(M,)`` of its frame in
    ``frames`` (indices into the problem's frames, ascending) and its index ``point`` ``(M,)``
    among the ``n_points`` observed points; ``image_height`` the frames' (the images are stacked);
    ``poses`` ``(F, 4, 4)`` all frames' LiDAR poses, at the time offset ``shift_s`` larger."""

    def __init__(
        self,
        xyz: np.ndarray,
        row: np.ndarray,
        point: np.ndarray,
        n_points: int,
        image_height: int,
        frames: np.ndarray,
        poses: np.ndarray,
        sampled: np.ndarray,
        shift_s: float = 0.0,
    ) -> None:
        self.xyz, self.point, self.n_points = xyz, point, n_points
        self.poses, self.shift_s = poses, shift_s
        #: ``(M,)`` the order in which the compiled sums sample the observations (each frame's
        #: own permuted: :func:`_by_image_position`), and ``(3, M)`` their points in it.
        self.sampled = sampled
        self.xyz_sampled = np.take(xyz, sampled, axis=1)
        #: ``(M,)`` the first row of each observation's frame in the stacked images.
        self.row_offset = frames[row].astype(np.float32) * image_height
        #: The frames that see something, each a run of the flat arrays: first index and length
        #: ``(R,)``, and ``run`` ``(M,)`` each observation's.
        per_frame = np.bincount(row, minlength=len(frames))
        self.run_lengths = per_frame[per_frame > 0]
        self.run_starts = np.cumsum(self.run_lengths) - self.run_lengths
        self.run = (np.cumsum(per_frame > 0) - 1)[row]
        #: ``(R,)`` each run's frame (an index into the problem's), and its first row in the
        #: stacked images.
        self.run_frames = frames[per_frame > 0]
        self.run_rows = self.run_frames.astype(np.int64) * image_height
        #: ``(n_points,)`` how many frames observe each point.
        self.point_counts = np.bincount(point, minlength=n_points)

    def transforms(self, T: np.ndarray, poses: np.ndarray | None = None) -> np.ndarray:
        """``(R, 3, 4)`` float32: what moves each run's points into its camera with
        ``T_cam_lidar`` ``T`` ``(4, 4)``, its frame placed at the LiDAR pose in ``poses``
        ``(F, 4, 4)`` instead of where it was observed (None: where it was)."""
        moves = np.repeat(T[None], len(self.run_frames), axis=0)
        if poses is not None:
            moves = moves @ invert(poses[self.run_frames]) @ self.poses[self.run_frames]
        return np.ascontiguousarray(moves[:, :3], dtype=np.float32)


def _bilinear(image: np.ndarray, u: np.ndarray, v: np.ndarray) -> np.ndarray:
    """Bilinear samples ``(M,)`` of ``image`` at pixels ``u, v`` ``(M,)`` (edges repeated)."""
    if not len(u):
        return np.zeros(0, dtype=np.float32)
    # OpenCV's remap (fast) takes maps of fewer than REMAP_LIMIT rows and columns: fold them.
    columns = 1024
    rows = -(-len(u) // columns)
    maps = np.zeros((2, rows * columns), dtype=np.float32)
    maps[0, : len(u)], maps[1, : len(u)] = u, v
    sampled = cv2.remap(
        image, maps[0].reshape(rows, columns), maps[1].reshape(rows, columns), cv2.INTER_LINEAR,
        borderMode=cv2.BORDER_REPLICATE,
    )  # fmt: skip
    return sampled.ravel()[: len(u)]


def _by_image_position(
    xyz: np.ndarray, run_lengths: list[int], T: np.ndarray, K: np.ndarray, width: int, height: int
) -> np.ndarray:
    """``(M,)`` a sampling order of the observations ``xyz`` ``(3, M)``, in runs of
    ``run_lengths`` (one per frame): each run's own, sorted by where its points fall in a
    ``width`` x ``height`` image with ``T_cam_lidar`` ``T`` ``(4, 4)`` and camera matrix ``K``:
    by row, then by one of ``65535 // height`` column bands (a 16-bit key, so that the sort is a
    radix sort). The searches move the extrinsic little between choices of observations, so the
    compiled sums sampled in this order walk each image instead of jumping about it."""
    # In float32, as the points are: an order is all this gives, and float64 took 5x as long.
    R, t = T[:3, :3].astype(np.float32), T[:3, 3, None].astype(np.float32)
    u, v, _, _ = _project((R @ xyz + t).T, K, width, height)
    bands = 65535 // height
    row = np.clip(v, 0, height - 1).astype(np.int64)
    column = np.clip(u, 0, width - 1)
    key = (row * bands + (column * bands / width).astype(np.int64)).astype(np.uint16)
    order = np.empty(xyz.shape[1], dtype=np.int64)
    start = 0
    for length in run_lengths:
        run = slice(start, start + length)
        order[run] = start + np.argsort(key[run], kind="stable")
        start += length
    return order


def _project(
    p: np.ndarray, K: np.ndarray, width: int, height: int
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Pinhole pixels ``u, v`` ``(M,)``, depths ``z`` and the in-image mask of camera points
    ``(M, 3)`` (points closer than 5 cm count as outside)."""
    z = p[:, 2]
    safe = np.where(z > 0.05, z, z.dtype.type(1))
    u = float(K[0, 0]) * p[:, 0] / safe + float(K[0, 2])
    v = float(K[1, 1]) * p[:, 1] / safe + float(K[1, 2])
    inside = (z > 0.05) & (u >= 0) & (u <= width - 1) & (v >= 0) & (v <= height - 1)
    return u, v, z, inside


def _tensor(a: np.ndarray, dtype: type) -> torch.Tensor:
    """``a`` as a contiguous CPU tensor of ``dtype`` for the compiled kernels (no copy where it
    is one already)."""
    import torch  # here, not at the top: the NumPy forms run without it

    return torch.from_numpy(np.ascontiguousarray(a, dtype=dtype))


def _shown_points(camera: np.ndarray, K: np.ndarray, width: int, height: int) -> np.ndarray:
    """Indices ``(S,)`` (ascending) of the points ``camera`` ``(3, N)`` (float32, camera
    coordinates) in the image and no more than :data:`DEPTH_TOLERANCE` behind the nearest point
    within :data:`OCCLUSION_PX` pixels (z-buffer): the map is sparse, and a surface in front hides
    what lies behind it between its points. The specification of :meth:`_Problem.kernel_visible`,
    and its stand-in."""
    u, v, z, inside = _project(camera.T, K, width, height)
    index = np.flatnonzero(inside)
    # Flat pixel indices: np.minimum.at takes them 7x faster than (row, column) pairs.
    pixel = np.rint(v[index]).astype(np.int64) * width + np.rint(u[index]).astype(np.int64)
    nearest = np.full(height * width, np.inf, dtype=np.float32)
    np.minimum.at(nearest, pixel, z[index])
    kernel = np.ones((OCCLUSION_PX, OCCLUSION_PX), np.uint8)
    nearest = cv2.erode(nearest.reshape(height, width), kernel).ravel()
    front = z[index] <= nearest[pixel] * (1 + DEPTH_TOLERANCE[0]) + DEPTH_TOLERANCE[1]
    return index[front]


def _observed(
    problem: _Problem, params: _Parameters, y: np.ndarray, frames: np.ndarray, stride: int = 1
) -> _Observations:
    """:meth:`_Problem.observations` at coefficients ``y`` ``(k,)``."""
    return problem.observations(params.pose(y), frames, stride, params.shift_s(y))


def _cost(problem: _Problem, params: _Parameters, y: np.ndarray, obs: _Observations) -> float:
    """:meth:`_Problem.cost` of the observations ``obs`` at coefficients ``y`` ``(k,)``."""
    return problem.cost(params.pose(y), obs, params.shift_s(y))


def _search(
    problem: _Problem, params: _Parameters, y: np.ndarray, frames: np.ndarray, xtol: float, stride: int = 1
) -> np.ndarray:
    """Powell from coefficients ``y`` ``(k,)`` over ``frames`` (indices), with the points and
    visibility at ``y`` (every ``stride``-th point, :meth:`_Problem.observations`), to ``xtol``
    (degrees / decimetres); returns the coefficients."""
    obs = _observed(problem, params, y, frames, stride)
    options = {"xtol": xtol, "ftol": 1e-6}
    return minimize(
        lambda z: _cost(problem, params, z, obs),
        y,
        method="Powell",
        bounds=params.bounds(),
        options=options,
    ).x


def _gradient(cost: Callable[[np.ndarray], float], x: np.ndarray, step: np.ndarray) -> np.ndarray:
    """Central finite differences of ``cost`` at ``x`` ``(k,)`` with steps ``step`` ``(k,)``."""
    eye = np.diag(step)
    return np.array([cost(x + e) - cost(x - e) for e in eye]) / (2 * step)


def _hessian(cost: Callable[[np.ndarray], float], x: np.ndarray, step: np.ndarray) -> np.ndarray:
    """Central finite differences of ``cost`` at ``x`` ``(k,)`` with steps ``step`` ``(k,)``: the
    Hessian ``(k, k)``."""
    eye = np.diag(step)
    centre = cost(x)
    plus, minus = np.array([cost(x + e) for e in eye]), np.array([cost(x - e) for e in eye])
    hessian = np.diag((plus - 2 * centre + minus) / step**2)
    for a, b in itertools.combinations(range(len(x)), 2):
        corners = [cost(x + sa * eye[a] + sb * eye[b]) for sa, sb in ((1, 1), (1, -1), (-1, 1), (-1, -1))]
        hessian[a, b] = hessian[b, a] = (corners[0] - corners[1] - corners[2] + corners[3]) / (
            4 * step[a] * step[b]
        )
    return hessian


def _jackknife_groups(n_frames: int) -> int:
    """How many stretches the jackknife splits ``n_frames`` frames into."""
    return min(JACKKNIFE_GROUPS, n_frames)


def _covariance(problem: _Problem, params: _Parameters, y: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Two covariances ``(7, 7)`` of the increment ``basis @ y`` (degrees, decimetres,
    :data:`TIME_UNIT_S`; nothing along the axes the basis leaves out): how the frames disagree,
    and how far the cost's own error may have moved its minimum (:func:`_spread` takes the
    larger).

    The first is a jackknife over :data:`JACKKNIFE_GROUPS` stretches of consecutive frames, each
    left out in turn. The estimate without a stretch is one Newton step from ``y``: the gradient
    of the cost without the stretch, the curvature of the cost over all frames (a full search per
    stretch wandered along the cost's flat valleys; each stretch's own curvature, from fewer
    frames, put a near-zero curvature somewhere and a 13 cm step along it). Pose errors of the
    odometry and moving things differ from stretch to stretch, so this sees more than the image
    noise. The second is the region where the cost stays within :data:`COST_TOLERANCE` of its
    value at ``y``: ``2 * COST_TOLERANCE * cost * inverse(curvature)``, wide where the cost is
    flat, and no wider than the search's reach."""
    every = np.arange(len(problem.grays))
    step = params.per_column(*STEP)
    observed = _observed(problem, params, y, every)
    values, vectors = np.linalg.eigh(_hessian(lambda z: _cost(problem, params, z, observed), y, step))
    # Only the curvature that holds the estimate: a direction the cost does not curve up in
    # moves nothing (it shows in the other stretches' steps instead).
    inverse = vectors @ np.diag(np.where(values > 0, 1 / np.maximum(values, 1e-12), 0.0)) @ vectors.T
    groups = np.array_split(every, _jackknife_groups(len(every)))
    steps = []
    for group in groups:
        obs = _observed(problem, params, y, np.setdiff1d(every, group))
        steps.append(-inverse @ _gradient(lambda z, obs=obs: _cost(problem, params, z, obs), y, step))
    steps = np.array(steps)
    g = len(groups)
    centred = steps - steps.mean(axis=0)
    jackknife = (g - 1) / g * centred.T @ centred
    rise = 2 * COST_TOLERANCE * _cost(problem, params, y, observed)
    # Where the cost does not curve up, the region reaches as far as the search may go.
    curvature = np.maximum(values, rise / max(SEARCH_REACH) ** 2)
    tolerance = vectors @ np.diag(rise / curvature) @ vectors.T
    return params.basis @ jackknife @ params.basis.T, params.basis @ tolerance @ params.basis.T


def _axis_std(covariance: np.ndarray) -> np.ndarray:
    """Per-axis standard deviations ``(n,)`` of a covariance ``(n, n)``."""
    return np.sqrt(np.maximum(np.diag(covariance), 0.0))


def _spread(jackknife: np.ndarray, tolerance: np.ndarray) -> np.ndarray:
    """Per-axis standard deviations ``(7,)`` of the estimate from the jackknife's and the cost
    tolerance's ``(7,)`` (degrees, decimetres, :data:`TIME_UNIT_S`): for the rotation, the
    translation and the time, the part whose vector is the longer. Not their sum: the
    stretches' disagreement moves the cost's minimum too, so it is part of what the tolerance
    covers (over the room's and the office's seeds 0-19, with the LiDAR map of a release that
    registered its sweeps once, the sum at the 0.5 % it needed held the truth in 111 of 116
    trials and left 31 results ``ok``; the larger at 0.7 %, 112 and 35)."""
    parts = (slice(3), slice(3, 6), slice(6, 7))
    return np.concatenate([max(jackknife[part], tolerance[part], key=np.linalg.norm) for part in parts])


def _rotation_translation_std(std: np.ndarray) -> tuple[float, float]:
    """Per-axis standard deviations ``(7,)`` (degrees, decimetres, time) as one rotation
    (degrees) and one translation (metres): the lengths of their vectors."""
    return float(np.linalg.norm(std[:3])), float(np.linalg.norm(std[3:6])) / 10.0


def _coarse_to_fine(
    problem: _Problem, params: _Parameters, y: np.ndarray, blurs: Sequence[float]
) -> np.ndarray:
    """:func:`_search` at each of ``blurs`` (a tail of :data:`BLUR_STAGES`) in turn, from ``y``;
    of the stages' ends, the one the sharpest images find most consistent, each scored on the
    points visible there (:func:`_self_cost`).

    Each stage scores the points visible at its start, and a stage can walk away from a better
    place on them: on the room's seed 2 a stage at 2 px left a point 0.1 cm from the truth's
    height for one 9.3 cm off, whose own points cost 10 % more."""
    ends = []
    for sigma, xtol in zip(blurs, XTOL[-len(blurs) :], strict=True):
        problem.blur(sigma)
        y = _search(problem, params, y, np.arange(len(problem.grays)), xtol, int(sigma // SAMPLE_BLUR))
        ends.append(y)
    return min(ends, key=lambda end: _self_cost(problem, params, end))


def _self_cost(problem: _Problem, params: _Parameters, y: np.ndarray) -> float:
    """The cost at ``y`` over the points visible there."""
    return _cost(problem, params, y, _observed(problem, params, y, np.arange(len(problem.grays))))


def _visible_at(problem: _Problem, params: _Parameters, y: np.ndarray) -> np.ndarray:
    """``(F, N)`` the map points each frame sees at coefficients ``y`` ``(k,)`` (the frames
    placed at its time offset)."""
    problem.at_shift(params.shift_s(y))
    return problem.visible(params.pose(y))


def _paired_costs(
    problem: _Problem, params: _Parameters, a: np.ndarray, b: np.ndarray
) -> tuple[float, float]:
    """The costs at coefficients ``a`` and ``b`` ``(k,)`` over all frames, both on the map points
    visible at both: how the flat check (:func:`_flat_translations`) compares a result with a
    step from it.

    Scored each on the points visible at it, the place that sees more points that agree easily
    wins: on the 20 s room (seed 2), 12 cm down the camera's y from the truth, 6 % more
    observations are in view (floor and walls) and the cost is 6.2 % lower, while on the points
    both see it is 3.0 % higher; three trials ended there, 11-12 cm off, and said ``ok``. The
    searches still score each place on its own points (:func:`_self_cost`): compared this way
    throughout, the 10 s room's first ten trials (seeds 0-3) ended up to 36 cm off instead of
    4.2 cm (two of seed 1's three), in 1.2 times the time (the points whose visibility differs,
    at depth edges, are the ones that tell a translation, and they drop out)."""
    seen = _visible_at(problem, params, a) & _visible_at(problem, params, b)
    obs = problem.observations(params.pose(a), np.arange(len(problem.grays)), 1, params.shift_s(a), seen)
    return _cost(problem, params, a, obs), _cost(problem, params, b, obs)


def _out_of_the_valley(problem: _Problem, params: _Parameters, y: np.ndarray) -> np.ndarray:
    """``y`` or a better minimum found by scanning along each free axis from ``y``.

    A rig that turns about one axis only (a robot on a floor) hardly constrains the translation
    along that axis, and the search can stop in a shallow local minimum of the long valley (the
    virtual room's seed 2: 27 cm off along the camera's y, with a barrier between it and the
    truth, which costs less). Each free axis is scanned at :data:`VALLEY_BLUR` over
    ±:data:`VALLEY_REACH`; from the best point, if better than ``y``, the fine stages run again,
    and the end with the lower cost wins.

    A move changes which map points hide others, so each point of a translation's scan is scored
    on the points visible *there*: scored on those visible at ``y``, the scan favours ``y`` (the
    room's seed 2 from 2° / 10 cm stopped 11.8 cm off along y: its own points made 10 cm towards
    the truth look 1 % worse, the points visible there 7 % better). A turn about the camera's
    centre hides nothing new, and its scan keeps the points of ``y`` (6 times cheaper).
    """
    every = np.arange(len(problem.grays))
    obs = _observed(problem, params, y, every)
    problem.blur(VALLEY_BLUR)
    along = np.linspace(-VALLEY_REACH, VALLEY_REACH, 2 * VALLEY_STEPS + 1)
    low, high = np.array(params.bounds()).T
    candidates, costs = [], []
    for axis, turns in zip(np.eye(len(y)), params.is_rotation(), strict=True):
        for z in (np.clip(y + a * axis, low, high) for a in along if a != 0):
            candidates.append(z)
            costs.append(_cost(problem, params, z, obs) if turns else _self_cost(problem, params, z))
    here = _cost(problem, params, y, obs)
    problem.blur(BLUR_STAGES[-1])
    if min(costs) >= here:
        return y
    other = _coarse_to_fine(problem, params, candidates[int(np.argmin(costs))], BLUR_STAGES[-3:])
    return other if _self_cost(problem, params, other) < _cost(problem, params, y, obs) else y


def _descend_translations(problem: _Problem, params: _Parameters, y: np.ndarray) -> np.ndarray:
    """``y`` moved along the free translations, at the current blur, while a step of
    :data:`DESCENT_STEPS_M` (each tried both ways, longest first) lowers the cost on the points
    visible where it lands (:func:`_self_cost`); after a move, a search of every axis from there
    settles the rotation, and the end with the lower cost wins.

    Along the axis a robot turns about, only floors and ceilings tell the translation, and the
    searches, which score the points visible at their start, stop anywhere along a flat valley
    (the room's seed 2 from 2° / 10 cm: the same cost to 1e-7 put one run 1.1 cm off along the
    camera's y, the next 9.1 cm, where 9 cm towards the truth its own points cost 7 % less)."""
    low, high = np.array(params.bounds()).T
    start = y
    best = _self_cost(problem, params, y)
    for step in np.asarray(DESCENT_STEPS_M) * 10.0:  # decimetres
        moved = True
        while moved:  # the cost falls at every move: it ends
            moved = False
            for column in np.flatnonzero(params.is_translation()):
                for sign in (-1.0, 1.0):
                    z = np.clip(y + sign * step * np.eye(len(y))[column], low, high)
                    cost = _self_cost(problem, params, z)
                    if cost < best:
                        y, best, moved = z, cost, True
    if y is start:
        return y
    settled = _search(problem, params, y, np.arange(len(problem.grays)), XTOL[-1])
    return settled if _self_cost(problem, params, settled) < best else y


def _refit_rotation(problem: _Problem, params: _Parameters, y: np.ndarray) -> np.ndarray:
    """``y`` with its rotation coefficients re-fitted (Powell, the points visible at ``y``, the
    translation held): where a step along a translation lands once the rotation follows it."""
    obs = _observed(problem, params, y, np.arange(len(problem.grays)))
    turns = params.is_rotation()

    def cost(rotation: np.ndarray) -> float:
        z = y.copy()
        z[turns] = rotation
        return _cost(problem, params, z, obs)

    refitted = y.copy()
    options = {"xtol": REFIT_XTOL_DEG, "ftol": 1e-6}
    refitted[turns] = minimize(cost, y[turns], method="Powell", options=options).x
    return refitted


def _flat_translations(problem: _Problem, params: _Parameters, y: np.ndarray) -> list[str]:
    """The free translations along which ``y`` is no clear minimum: a point
    :data:`PROFILE_STEP_M` to either side costs less than :data:`MIN_RISE` more (each compared
    with ``y`` on the points visible at both, :func:`_paired_costs`, at the current blur, with the
    rotation re-fitted to the step where the plain step rises less than :data:`REFIT_BELOW` ×
    :data:`MIN_RISE`); one line per such axis.

    The jackknife cannot see a flat valley: every stretch of frames shares it (and the odometry's
    errors, which move its lowest point), so the stretches agree on a point anywhere along it. A
    turn makes up for a shift on far surfaces, so the valley runs along both: on the 20 s room a
    result 13 cm above the truth rose 3.2 % 10 cm back down with its rotation held (a clear
    minimum, ``ok``) and 1.9 % with the rotation re-fitted."""
    step = PROFILE_STEP_M * 10.0  # decimetres
    flat = []

    def rise(z: np.ndarray) -> float:
        here, there = _paired_costs(problem, params, y, z)
        return there / here

    for column in np.flatnonzero(params.is_translation()):
        lowest = np.inf
        for sign in (-1, 1):
            stepped = y + sign * step * np.eye(len(y))[column]
            ratio = rise(stepped)
            if ratio < 1 + REFIT_BELOW * MIN_RISE:
                ratio = min(ratio, rise(_refit_rotation(problem, params, stepped)))
            lowest = min(lowest, ratio)
        if lowest < 1 + MIN_RISE:
            direction = np.round(params.basis[3:6, column], 2).tolist()
            change = 100 * (lowest - 1)
            moved = f"moving the camera {PROFILE_STEP_M * 100:.0f} cm along {direction} (camera frame)"
            if change < 0:
                flat.append(f"{moved} lowers the cost by {-change:.1f} %: the result is no minimum along it")
            else:
                flat.append(
                    f"{moved} raises the cost by only {change:.1f} % (under {100 * MIN_RISE:.0f} %, the "
                    "rotation following): the frames hardly tell the translation along it"
                )
    return flat


def _straight_reason(turn_deg: float, kept: str) -> str:
    """Why a straight drive (turning at most ``turn_deg``) leaves the extrinsic unsure; ``kept``
    says what was kept from the guess."""
    return (
        f"the rig turned at most {turn_deg:.1f}° between frames (under {MIN_TURN_DEG:.0f}°): driving "
        "straight, the map looks alike under a roll about the direction of travel or a shift along "
        f"it, {kept}"
    )


def _straight_travel(frames: Sequence[ConsistencyFrame]) -> tuple[float, np.ndarray | None]:
    """The most the LiDAR turned between any two ``frames`` (degrees) and, when that is under
    :data:`MIN_TURN_DEG`, its unit direction of travel ``(3,)`` in the LiDAR frame (None when it
    turned more, or moved less than :data:`MIN_TRAVEL_M`)."""
    rotations = np.array([f.T_world_lidar[:3, :3] for f in frames])
    relative = np.einsum("aji,bjk->abik", rotations, rotations)  # R_a^T R_b
    cosine = np.clip((np.trace(relative, axis1=2, axis2=3) - 1) / 2, -1.0, 1.0)
    turn = float(np.degrees(np.arccos(cosine.min())))
    positions = np.array([f.T_world_lidar[:3, 3] for f in frames])
    centred = positions - positions.mean(axis=0)
    direction = np.linalg.svd(centred, full_matrices=False)[2][0]
    if turn >= MIN_TURN_DEG or np.ptp(centred @ direction) < MIN_TRAVEL_M:
        return turn, None
    in_lidar = np.einsum("nji,j->ni", rotations, direction).mean(axis=0)
    return turn, in_lidar / np.linalg.norm(in_lidar)


def _observable_basis(travel_cam: np.ndarray | None, timed: bool) -> np.ndarray:
    """``(7, k)``: all six axes, or without the rotation about and the translation along the
    unit direction of travel ``travel_cam`` ``(3,)`` (camera frame) of a straight drive; and the
    time offset where ``timed``."""
    if travel_cam is None:
        basis = np.eye(7, 6)
    else:
        across = np.linalg.svd(travel_cam[None, :])[2][1:].T  # (3, 2) orthonormal, normal to it
        basis = np.zeros((7, 4))
        basis[:3, :2], basis[3:6, 2:] = across, across
    return np.column_stack([basis, np.eye(7)[:, 6]]) if timed else basis


def photo_consistency_extrinsic(
    frames: Sequence[ConsistencyFrame],
    camera: CameraModel,
    lidar_map: LidarMap,
    T_init: np.ndarray,
    search_straight: bool = True,
    offset_reach_s: float = 0.0,
    threads: int = 1,
) -> ExtrinsicResult:
    """Refine ``T_cam_lidar`` ``(4, 4)`` from a rough guess so that the map's points look alike in
    all ``frames``. Never raises on weak data: too few frames or points give the guess back with
    a ``poorly constrained`` verdict and the reason.

    Where the time offset that placed the frames may be up to ``offset_reach_s`` off (and every
    frame has its instant ``t_ns``), the offset is searched with the extrinsic, within that reach
    (the frames placed again along the map's trajectory); the JSON's ``time_offset_shift`` gives
    how much larger it came out (s) and its spread. Not on a straight drive: there a change of
    the offset is a shift along the travel, which is kept.

    A rig that drives straight (turning less than :data:`MIN_TURN_DEG`) sees the surfaces beside
    its path, which lie along the direction of travel, shift within themselves under a roll about
    that direction or a move along it; they look alike in every frame either way. Those two are
    kept from the guess, the other four refined, and the verdict says so; with
    ``search_straight`` False the guess is kept whole without a search (its result could not be
    applied: 15 s of the quick demo's 3 s straight recording).

    ``threads``: the cost's and the visibility's threads (the same result with any number; one
    where another process keeps the cores busy)."""
    # NumPy's matrix products here are 3 x N, for which one BLAS thread does: OpenBLAS's others,
    # spinning while they wait for the next product, take the cores the kernels' threads need
    # (a KITTI-size drive's visibility on two threads: 57 -> 41 ms a call).
    with ThreadpoolController().limit(limits=1, user_api="blas"):
        return _refined_extrinsic(frames, camera, lidar_map, T_init, search_straight, offset_reach_s, threads)


def _refined_extrinsic(
    frames: Sequence[ConsistencyFrame],
    camera: CameraModel,
    lidar_map: LidarMap,
    T_init: np.ndarray,
    search_straight: bool,
    offset_reach_s: float,
    threads: int,
) -> ExtrinsicResult:
    """:func:`photo_consistency_extrinsic` with its arguments."""
    method = METHOD.format(len(frames))
    timing = None
    if offset_reach_s > 0 and all(f.t_ns is not None for f in frames):
        timing = _Timing(lidar_map.trajectory, np.array([f.t_ns for f in frames], dtype=np.int64))
    problem = _Problem(frames, camera, lidar_map.points, timing, threads)
    every = np.arange(len(frames))
    initial = problem.visible(T_init)
    n_points = int((initial.sum(axis=0) >= MIN_VIEWS).sum())
    if len(frames) < MIN_FRAMES or n_points < MIN_POINTS:
        reason = (
            f"only {len(frames)} frames and {n_points} map points seen by {MIN_VIEWS} of them near the "
            f"initial guess; need {MIN_FRAMES} and {MIN_POINTS}"
        )
        return _result(T_init, T_init, "poorly constrained", [reason], (np.inf,) * 2, {}, n_points, method)

    turn, travel = _straight_travel(frames)
    travel_cam = None if travel is None else T_init[:3, :3] @ travel
    if travel_cam is not None and not search_straight:
        reason = _straight_reason(
            turn, "so the guess was kept whole (a search of the other four axes was skipped)"
        )
        extra = {
            "frames": len(frames),
            "turn_deg": turn,
            "kept_from_guess": {"travel_direction_cam": travel_cam.tolist()},
        }
        return _result(T_init, T_init, "poorly constrained", [reason], (np.inf,) * 2, extra, n_points, method)
    timed = timing is not None and travel_cam is None
    params = _Parameters(T_init, _observable_basis(travel_cam, timed), offset_reach_s / TIME_UNIT_S)
    y = _coarse_to_fine(problem, params, np.zeros(params.basis.shape[1]), BLUR_STAGES)
    y = _out_of_the_valley(problem, params, y)
    y = _descend_translations(problem, params, y)
    obs = _observed(problem, params, y, every)
    cost_init, cost_final = problem.cost(T_init, obs), _cost(problem, params, y, obs)
    jackknife, tolerance = (_axis_std(c) for c in _covariance(problem, params, y))
    std = _spread(jackknife, tolerance)
    rot_std, trans_std = _rotation_translation_std(std)
    frames_std, flat_std = _rotation_translation_std(jackknife), _rotation_translation_std(tolerance)
    interval_95 = jackknife_interval_95(_jackknife_groups(len(frames)))
    reasons = []
    if travel_cam is not None:
        reasons.append(_straight_reason(turn, "so both were kept from the guess"))
        rot_std = trans_std = np.inf  # nothing is known along the axes kept
    seen = obs.n_points  # the points at least MIN_VIEWS frames see at the result
    if seen < MIN_SEEN_FRACTION * n_points:
        reasons.append(
            f"the result sees {seen} map points in {MIN_VIEWS} frames, the guess {n_points}: the search "
            "ran off to where little of the map is in view"
        )
    low, high = np.array(params.bounds()).T
    bounded = np.isclose(y, low, atol=1e-3) | np.isclose(y, high, atol=1e-3)
    timed_column = ~(params.is_rotation() | params.is_translation())
    if bounded[~timed_column].any():
        reasons.append(
            f"the search reached its bound ({SEARCH_REACH[0]:.0f}° / {SEARCH_REACH[1] * 10:.0f} cm from "
            "the guess)"
        )
    reasons += _flat_translations(problem, params, y)
    if cost_final >= cost_init:
        reasons.append(
            "the map's points agree no better across frames than at the initial guess: kept the guess"
        )
        y = np.zeros_like(y)
    if np.isfinite(rot_std) and rot_std > MAX_ROT_STD_DEG:
        reasons.append(
            f"rotation uncertain by ±{rot_std:.2f}° (1σ; limit {MAX_ROT_STD_DEG}°), the larger of "
            f"±{frames_std[0]:.2f}° between stretches of frames and ±{flat_std[0]:.2f}° where the cost "
            f"stays within {COST_TOLERANCE:.1%} of its lowest"
        )
    if np.isfinite(trans_std) and trans_std > MAX_TRANS_STD_M:
        reasons.append(
            f"translation uncertain by ±{trans_std * 100:.1f} cm (1σ; limit {MAX_TRANS_STD_M * 100:.1f} "
            f"cm), the larger of ±{frames_std[1] * 100:.1f} cm between stretches of frames and "
            f"±{flat_std[1] * 100:.1f} cm where the cost stays within {COST_TOLERANCE:.1%} of its lowest"
        )
    extra = {
        "photo_consistency": {"init": cost_init, "final": cost_final},
        "rotation_std_deg_xyz": (std[:3]).tolist(),
        "translation_std_m_xyz": (std[3:6] / 10.0).tolist(),
        "std_parts": {
            name: {"rotation_deg": rotation, "translation_m": translation}
            for name, (rotation, translation) in (("jackknife", frames_std), ("cost_tolerance", flat_std))
        },
        "frames": len(frames),
        "turn_deg": turn,
    }
    if travel_cam is not None:
        extra["kept_from_guess"] = {"travel_direction_cam": travel_cam.tolist()}
    if timed:
        # The caller judges what a shift at the window's edge means (the offset may lie past it).
        extra["time_offset_shift"] = {
            "shift_s": params.shift_s(y),
            "std_s": float(std[6] * TIME_UNIT_S),
            "interval_95_s": float(interval_95 * std[6] * TIME_UNIT_S),
            "reach_s": offset_reach_s,
            "at_reach": bool(bounded[timed_column].any()),
            "std_parts_s": {
                "jackknife": float(jackknife[6] * TIME_UNIT_S),
                "cost_tolerance": float(tolerance[6] * TIME_UNIT_S),
            },
        }
    verdict = "poorly constrained" if reasons else "ok"
    return _result(
        params.pose(y), T_init, verdict, reasons, (rot_std, trans_std), extra, n_points, method, interval_95
    )


def _result(
    T: np.ndarray,
    T_init: np.ndarray,
    verdict: str,
    reasons: list[str],
    stds: tuple[float, float],
    extra: dict,
    n_points: int,
    method: str,
    interval_95: float = NORMAL_95,
) -> ExtrinsicResult:
    return ExtrinsicResult(
        T_cam_lidar=T.copy(),
        T_init=T_init.copy(),
        verdict=verdict,
        reasons=reasons,
        rotation_std_deg=stds[0],
        translation_std_m=stds[1],
        mutual_information={},
        edge_score={},
        n_points=n_points,
        n_edge_points=0,
        method=method,
        extra=extra,
        interval_95=interval_95,
    )
