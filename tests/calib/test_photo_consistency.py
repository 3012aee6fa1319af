"""Pieces of the photo-consistency extrinsic that need no recording: which axes a drive observes,
what hides a map point, and which points the map keeps."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from calib import photo_consistency
from calib.lidar_map import LidarMap, _one_per_voxel
from calib.photo_consistency import (
    COST_TOLERANCE,
    MIN_POINTS,
    MIN_RISE,
    MIN_TURN_DEG,
    PROFILE_STEP_M,
    SEARCH_REACH,
    TIME_UNIT_S,
    ConsistencyFrame,
    _covariance,
    _descend_translations,
    _flat_translations,
    _observable_basis,
    _Parameters,
    _Problem,
    _spread,
    _straight_travel,
    _Timing,
)
from rig.camera import CameraModel
from rig.trajectory import Trajectory
from rig.transforms import make_transform


def _frames(yaw_deg: np.ndarray, positions: np.ndarray) -> list[ConsistencyFrame]:
    image = np.zeros((48, 64), np.uint8)
    return [
        ConsistencyFrame(image, make_transform(Rotation.from_euler("z", yaw, degrees=True).as_matrix(), p))
        for yaw, p in zip(yaw_deg, positions, strict=True)
    ]


def test_a_straight_drive_keeps_the_roll_about_and_the_shift_along_its_travel() -> None:
    rng = np.random.default_rng(0)
    along = np.linspace(0.0, 20.0, 12)
    wobble = rng.normal(0.0, 0.2, 12)  # degrees of yaw: a car on a straight road
    turn, travel = _straight_travel(_frames(wobble, np.column_stack([along, 0.05 * wobble, 0 * along])))
    assert turn < MIN_TURN_DEG
    assert abs(abs(travel[0]) - 1.0) < 1e-3  # the LiDAR's x, the way it drives

    T_init = make_transform(
        Rotation.from_euler("xyz", (-90, 0, -90), degrees=True).as_matrix(), (0.1, -0.2, 0.0)
    )
    travel_cam = T_init[:3, :3] @ travel
    params = _Parameters(T_init, _observable_basis(travel_cam, timed=False))
    assert params.basis.shape == (7, 4)
    for _ in range(5):
        T = params.pose(rng.normal(0.0, 3.0, 4))
        turned = Rotation.from_matrix(T[:3, :3] @ T_init[:3, :3].T).as_rotvec()
        assert abs(turned @ travel_cam) < 1e-9
        assert abs((T[:3, 3] - T_init[:3, 3]) @ travel_cam) < 1e-9

    turning = _frames(np.linspace(0.0, 40.0, 12), np.column_stack([along, along**2 / 40, 0 * along]))
    turn, travel = _straight_travel(turning)
    assert turn > 39.0 and travel is None
    np.testing.assert_array_equal(_observable_basis(None, timed=False), np.eye(7, 6))
    np.testing.assert_array_equal(_observable_basis(None, timed=True), np.eye(7))


def test_moving_things_hide_the_map_points_behind_them() -> None:
    """A wall 10 m ahead; a car (not in the map) 5 m ahead covers its middle in one frame."""
    camera = CameraModel("pinhole", 64, 48, np.array([[40.0, 0, 32], [0, 40.0, 24], [0, 0, 1]]), np.zeros(0))
    u, v = np.meshgrid(np.linspace(-4, 4, 41), np.linspace(-3, 3, 31))
    wall = np.column_stack([u.ravel(), v.ravel(), np.full(u.size, 10.0)])  # camera = LiDAR frame
    cu, cv = np.meshgrid(np.linspace(-0.5, 0.5, 21), np.linspace(-0.5, 0.5, 21))
    car = np.column_stack([cu.ravel(), cv.ravel(), np.full(cu.size, 5.0)])
    image = np.zeros((48, 64), np.uint8)
    frames = [ConsistencyFrame(image, np.eye(4)), ConsistencyFrame(image, np.eye(4), car)]
    seen = _Problem(frames, camera, wall).visible(np.eye(4))
    assert seen[0].all()
    # The car covers ±4 px, the occlusion window 3 px more: ±1.75 m of the wall.
    assert not seen[1][(np.abs(wall[:, 0]) < 1.0) & (np.abs(wall[:, 1]) < 1.0)].any()
    assert seen[1][(np.abs(wall[:, 0]) > 2.0) | (np.abs(wall[:, 1]) > 2.0)].all()


def test_coarse_stages_score_every_kth_point_but_never_fewer_than_the_minimum() -> None:
    """A wall every frame sees: a stride keeps every k-th point, its observations in every frame,
    and stops short of leaving fewer than MIN_POINTS."""
    camera = CameraModel("pinhole", 64, 48, np.array([[40.0, 0, 32], [0, 40.0, 24], [0, 0, 1]]), np.zeros(0))
    u, v = np.meshgrid(np.linspace(-2, 2, 100), np.linspace(-1.5, 1.5, 60))  # 6000 points, 10 m ahead
    wall = np.column_stack([u.ravel(), v.ravel(), np.full(u.size, 10.0)])
    image = np.zeros((48, 64), np.uint8)
    problem = _Problem([ConsistencyFrame(image, np.eye(4)) for _ in range(3)], camera, wall)
    every = np.arange(3)
    full = problem.observations(np.eye(4), every)
    assert full.n_points == len(wall) and full.xyz.shape[1] == 3 * len(wall)
    halved = problem.observations(np.eye(4), every, stride=2)
    assert halved.n_points == len(wall) // 2 and halved.xyz.shape[1] == 3 * (len(wall) // 2)
    np.testing.assert_allclose(halved.xyz[:, : halved.n_points], wall[::2].T, atol=1e-6)  # float32
    assert problem.observations(np.eye(4), every, stride=8).n_points == len(wall[::3]) >= MIN_POINTS


def test_observations_follow_the_time_offset_as_the_frames_placed_again() -> None:
    """A rig turning 10°/s and driving 1 m/s past a wall: the observations' transforms to a time
    offset 20 ms larger put the points where the frames placed there see them."""
    camera = CameraModel("pinhole", 64, 48, np.array([[40.0, 0, 32], [0, 40.0, 24], [0, 0, 1]]), np.zeros(0))
    u, v = np.meshgrid(np.linspace(-0.5, 0.5, 60), np.linspace(-0.5, 0.5, 40))
    wall = np.column_stack([u.ravel(), v.ravel(), np.full(u.size, 10.0)])
    knots = np.arange(0, 1_000_000_001, 100_000_000)
    poses = [
        make_transform(Rotation.from_euler("y", 10 * t * 1e-9, degrees=True).as_matrix(), (t * 1e-9, 0, 0))
        for t in knots
    ]
    timing = _Timing(Trajectory.from_poses(knots, np.stack(poses)), np.array([250, 500, 750]) * 1_000_000)
    image = np.zeros((48, 64), np.uint8)
    frames = [
        ConsistencyFrame(image, pose, t_ns=t) for pose, t in zip(timing.poses(0.0), timing.t_ns, strict=True)
    ]
    problem = _Problem(frames, camera, wall, timing)
    every = np.arange(3)
    T = make_transform(Rotation.from_euler("x", 1.0, degrees=True).as_matrix(), (0.1, 0.0, 0.0))
    observed = problem.observations(T, every)
    placed = problem.observations(T, every, shift_s=0.02)
    assert observed.n_points == placed.n_points == len(wall) and placed.shift_s == 0.02
    moves = observed.transforms(T, problem.poses_at(0.02))
    assert moves.shape == (3, 3, 4) and moves.dtype == np.float32
    runs = zip(moves, observed.run_starts, observed.run_lengths, strict=True)
    in_camera = np.hstack([m[:, :3] @ observed.xyz[:, a : a + n] + m[:, 3, None] for m, a, n in runs])
    np.testing.assert_allclose(in_camera, T[:3, :3] @ placed.xyz + T[:3, 3, None], atol=1e-5)
    np.testing.assert_allclose(observed.transforms(T)[1], T[:3], atol=1e-7)  # where observed
    # 20 ms at 10°/s and 1 m/s: the points have moved by 0.2° about y and 2 cm.
    assert 0.02 < np.abs(placed.xyz - observed.xyz).max() < 0.2


def test_the_map_keeps_measured_points_one_per_voxel() -> None:
    """Points on the two faces of an edge: a voxel's mean would float between them."""
    rng = np.random.default_rng(1)
    floor = np.column_stack([rng.uniform(0, 1, 500), rng.uniform(0, 1, 500), np.zeros(500)])
    wall = np.column_stack([rng.uniform(0, 1, 500), np.zeros(500), rng.uniform(0, 1, 500)])
    points = np.vstack([floor, wall])
    kept = _one_per_voxel(points, 0.1)
    assert np.all(np.diff(kept) > 0)
    chosen = points[kept]
    assert np.all((chosen[:, 2] == 0) | (chosen[:, 1] == 0))  # every one on a face
    keys = np.floor(chosen / 0.1).astype(int)
    assert (
        len(np.unique(keys, axis=0))
        == len(kept)
        == len(np.unique(np.floor(points / 0.1).astype(int), axis=0))
    )


def test_moving_points_near_a_time() -> None:
    t_ns = np.arange(10, dtype=np.int64) * 20_000_000  # every 20 ms
    trajectory = Trajectory.from_poses(np.array([0, 10**9]), np.stack([np.eye(4)] * 2))
    lidar_map = LidarMap(trajectory, np.zeros((0, 3)), np.arange(30.0).reshape(10, 3), t_ns)
    near = lidar_map.moving_near(100_000_000)  # 100 ms: the points at 60..140 ms
    np.testing.assert_array_equal(near[:, 0], [9.0, 12.0, 15.0, 18.0, 21.0])


def test_a_flat_valley_along_a_translation_is_named(monkeypatch) -> None:
    """The profile check: a cost that rises steeply along the camera's x and z but by only a
    third of :data:`MIN_RISE` 10 cm along its y (a robot that turns about the vertical alone)
    names y, and only y; rotations are not probed."""
    curvature = np.array([1.0, 1.0, 1.0, 5.0, MIN_RISE / 3, 5.0])  # per (PROFILE_STEP_M)^2

    def cost(y: np.ndarray) -> float:
        return 1.0 + float(curvature @ (y / (PROFILE_STEP_M * 10.0)) ** 2)

    monkeypatch.setattr(photo_consistency, "_paired_costs", lambda problem, params, a, b: (cost(a), cost(b)))
    monkeypatch.setattr(photo_consistency, "_refit_rotation", lambda problem, params, y: y)  # no coupling
    params = _Parameters(np.eye(4), np.eye(7, 6))
    reasons = _flat_translations(None, params, np.zeros(6))
    assert len(reasons) == 1 and "[0.0, 1.0, 0.0]" in reasons[0] and "1.0 %" in reasons[0]
    curvature[4] = 2 * MIN_RISE
    assert _flat_translations(None, params, np.zeros(6)) == []
    curvature[4] = -MIN_RISE  # a result that is no minimum along y: the cost falls 3 % there
    reasons = _flat_translations(None, params, np.zeros(6))
    assert len(reasons) == 1 and "lowers the cost by 3.0 %" in reasons[0] and "no minimum" in reasons[0]


class _TiltedValley:
    """A stand-in problem whose cost (of ``T_cam_lidar``) has a valley along the camera's y that a
    turn about its x follows: a step of 10 cm up with the rotation held costs 2 × MIN_RISE more,
    with the rotation turned 1° along with it almost nothing (a turn makes up for a shift on far
    surfaces)."""

    grays = (None,)  # one frame

    def at_shift(self, shift_s: float) -> None:
        assert shift_s == 0.0

    def visible(self, T: np.ndarray) -> np.ndarray:
        return np.ones((1, 1), dtype=bool)

    def observations(self, T: np.ndarray, frames: np.ndarray, stride: int, shift_s: float, seen=None) -> None:
        return None

    def cost(self, T: np.ndarray, obs: None, shift_s: float) -> float:
        turn = Rotation.from_matrix(T[:3, :3]).as_rotvec(degrees=True)
        shift = T[:3, 3] / PROFILE_STEP_M
        valley = 2 * MIN_RISE * (shift[1] - turn[0]) ** 2 + MIN_RISE / 10 * turn[0] ** 2
        return 1.0 + valley + 5 * (shift[0] ** 2 + shift[2] ** 2) + turn[1] ** 2 + turn[2] ** 2


def test_a_valley_that_a_turn_follows_is_named_with_the_rotation_refitted(monkeypatch) -> None:
    """On the 20 s room a result 13 cm above the truth rose 3.2 % 10 cm back with its rotation held
    and said ok; with the rotation re-fitted to the step the rise is 1.9 %."""
    params = _Parameters(np.eye(4), np.eye(7, 6))
    reasons = _flat_translations(_TiltedValley(), params, np.zeros(6))
    assert len(reasons) == 1 and "[0.0, 1.0, 0.0]" in reasons[0] and "rotation following" in reasons[0]
    monkeypatch.setattr(photo_consistency, "_refit_rotation", lambda problem, params, y: y)
    assert _flat_translations(_TiltedValley(), params, np.zeros(6)) == []


class _SeenByPlace:
    """A stand-in problem of one frame and four map points: at the identity the first three are in
    view, elsewhere the last three. Its cost counts the points it is given and adds how far the
    camera moved along its x (m)."""

    grays = (None,)

    def at_shift(self, shift_s: float) -> None:
        assert shift_s == 0.0

    def visible(self, T: np.ndarray) -> np.ndarray:
        seen = np.zeros((1, 4), dtype=bool)
        seen[0, :3] = True
        return seen if np.allclose(T, np.eye(4)) else np.roll(seen, 1, axis=1)

    def observations(self, T: np.ndarray, frames: np.ndarray, stride: int, shift_s: float, seen=None):
        return seen

    def cost(self, T: np.ndarray, obs: np.ndarray, shift_s: float) -> float:
        return float(obs.sum()) + T[0, 3]


def test_two_places_are_compared_on_the_points_both_see() -> None:
    """The flat check scores a result and a step from it on the two points in view at both, each
    place with its own pose (scored each on its own points, the place seeing more wins)."""
    params = _Parameters(np.eye(4), np.eye(7, 6))
    moved = np.array([0.0, 0.0, 0.0, 1.0, 0.0, 0.0])  # 1 dm along x
    here, there = photo_consistency._paired_costs(_SeenByPlace(), params, np.zeros(6), moved)
    assert here == pytest.approx(2.0) and there == pytest.approx(2.1)


def test_the_last_descent_walks_a_flat_valley_and_keeps_the_better_end(monkeypatch) -> None:
    """A cost whose lowest point lies 12 cm along the camera's y (and 0.5° about its x) from
    where the searches stopped: the descent moves only the translations and ends within its
    finest step of 12 cm; the search of every axis afterwards is kept only where it costs less."""
    lowest = np.array([0.5, 0.0, 0.0, 0.0, 1.2, 0.0])  # degrees, decimetres

    def cost(problem, params, y) -> float:
        return 1.0 + float(np.sum((y - lowest) ** 2))

    monkeypatch.setattr(photo_consistency, "_self_cost", cost)
    params, problem = _Parameters(np.eye(4), np.eye(7, 6)), SimpleNamespace(grays=[None] * 4)
    walks_back = lambda problem, params, y, frames, xtol: np.zeros(6)  # noqa: E731
    monkeypatch.setattr(photo_consistency, "_search", walks_back)
    y = _descend_translations(problem, params, np.zeros(6))
    assert abs(y[4] - 1.2) <= 0.25 / 2 and np.allclose(np.delete(y, 4), 0.0)
    monkeypatch.setattr(photo_consistency, "_search", lambda problem, params, y, frames, xtol: lowest)
    assert np.allclose(_descend_translations(problem, params, np.zeros(6)), lowest)
    start = lowest.copy()  # no step helps: the start comes back untouched
    assert _descend_translations(problem, params, start) is start


class _Bowl:
    """A stand-in problem of ten frames whose cost (of ``T_cam_lidar``, about the identity) is a
    bowl of the given curvatures along (rotation degrees, translation decimetres); each frame's
    own bowl sits ``frame_offsets[i]`` (in ``y``) from the others'."""

    def __init__(self, curvature: np.ndarray, frame_offsets: np.ndarray, lowest: float = 0.02) -> None:
        self.grays = [None] * len(frame_offsets)
        self.curvature, self.offsets, self.lowest = curvature, frame_offsets, lowest

    def observations(self, T: np.ndarray, frames: np.ndarray, stride: int, shift_s: float) -> np.ndarray:
        return frames

    def cost(self, T: np.ndarray, frames: np.ndarray, shift_s: float) -> float:
        y = np.r_[Rotation.from_matrix(T[:3, :3]).as_rotvec(degrees=True), T[:3, 3] * 10]
        per_frame = [0.5 * self.curvature @ (y - self.offsets[i]) ** 2 for i in frames]
        return self.lowest + float(np.mean(per_frame))


def test_the_spread_adds_how_far_the_cost_stays_within_its_tolerance() -> None:
    """Frames that agree leave the jackknife nothing, but the cost's own error still moves its
    minimum: the region where the cost rises by under COST_TOLERANCE is in the covariance, the
    wider the flatter the cost, and no wider than the search's reach where it is flat."""
    curvature = np.array([0.04, 0.04, 0.01, 0.2, 0.05, 0.2])
    params = _Parameters(np.eye(4), np.eye(7, 6))
    jackknife, tolerance = _covariance(_Bowl(curvature, np.zeros((10, 6))), params, np.zeros(6))
    np.testing.assert_allclose(jackknife, 0.0, atol=1e-12)
    expected = np.r_[2 * COST_TOLERANCE * 0.02 / curvature, 0.0]  # nothing along the time, not searched
    np.testing.assert_allclose(np.diag(tolerance), expected, rtol=1e-3)

    flat = curvature.copy()
    flat[4] = 0.0  # no rise along the camera's y
    _, tolerance = _covariance(_Bowl(flat, np.zeros((10, 6))), params, np.zeros(6))
    assert np.sqrt(tolerance[4, 4]) == pytest.approx(max(SEARCH_REACH), rel=1e-3)

    # Frames whose own minima scatter along the x axis: the jackknife sees them.
    scatter = np.zeros((10, 6))
    scatter[:, 3] = np.random.default_rng(0).normal(0.0, 0.3, 10)
    jackknife, _ = _covariance(_Bowl(curvature, scatter), params, np.zeros(6))
    assert jackknife[3, 3] > 1e-3 and np.allclose(np.delete(np.diag(jackknife), 3), 0.0, atol=1e-9)


def test_the_time_offset_is_searched_with_the_extrinsic() -> None:
    """A bowl whose lowest point is 5 ms later than the offset used, with the time as the
    search's seventh coefficient: its coefficient counts TIME_UNIT_S, its bounds are the window
    given, and the covariance has its curvature's region along it."""
    params = _Parameters(np.eye(4), _observable_basis(None, timed=True), time_reach=0.03 / TIME_UNIT_S)
    y = np.r_[np.zeros(6), 0.005 / TIME_UNIT_S]
    assert params.shift_s(y) == pytest.approx(0.005)
    np.testing.assert_allclose(params.pose(y), np.eye(4))
    assert params.bounds()[6] == pytest.approx((-3.0, 3.0))
    assert params.bounds()[0] == (-SEARCH_REACH[0], SEARCH_REACH[0])
    assert params.per_column(1.0, 2.0, 3.0).tolist() == [1.0] * 3 + [2.0] * 3 + [3.0]

    class TimedBowl(_Bowl):
        def cost(self, T: np.ndarray, frames: np.ndarray, shift_s: float) -> float:
            return super().cost(T, frames, shift_s) + 0.5 * 0.1 * (shift_s / TIME_UNIT_S - 0.5) ** 2

    curvature = np.array([0.04, 0.04, 0.01, 0.2, 0.05, 0.2])
    _, tolerance = _covariance(TimedBowl(curvature, np.zeros((10, 6))), params, np.r_[np.zeros(6), 0.5])
    assert tolerance[6, 6] == pytest.approx(2 * COST_TOLERANCE * 0.02 / 0.1, rel=1e-3)


def test_the_spread_is_the_larger_part_for_the_rotation_and_for_the_translation() -> None:
    jackknife = np.array([0.3, 0.0, 0.0, 0.1, 0.1, 0.0, 0.2])  # stretches disagree in rotation
    tolerance = np.array([0.1, 0.1, 0.1, 0.0, 0.3, 0.0, 0.1])  # the cost is flat along one translation
    np.testing.assert_array_equal(_spread(jackknife, tolerance), [0.3, 0.0, 0.0, 0.0, 0.3, 0.0, 0.2])
    np.testing.assert_array_equal(_spread(tolerance, jackknife), [0.3, 0.0, 0.0, 0.0, 0.3, 0.0, 0.2])
