"""The compiled photo-consistency sums and visibility against their NumPy specifications, and the
stand-ins where no compiler is at hand."""

from __future__ import annotations

import tomllib
from pathlib import Path

import cv2
import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from calib import photo_consistency, photo_kernel
from calib.photo_consistency import ConsistencyFrame, _Problem
from rig.camera import CameraModel
from rig.transforms import make_transform

CAMERA = CameraModel("pinhole", 160, 120, np.array([[100.0, 0, 80], [0, 100.0, 60], [0, 0, 1]]), np.zeros(0))


def _room_problem(occluders: int = 0) -> _Problem:
    """Six frames looking at a textured room corner (two walls and a floor, some points behind the
    cameras or off their images), each image a different gain and offset of one smooth texture;
    each frame with ``occluders`` points of its own between the cameras and the walls."""
    rng = np.random.default_rng(3)
    a, b = rng.uniform(-3, 3, (2, 3000))
    world = np.vstack([
        np.column_stack([a, b, np.full_like(a, 6.0)]),  # the wall ahead
        np.column_stack([np.full_like(a, 3.0), b, 3 + a]),  # the wall on the right
        np.column_stack([a, np.full_like(a, 1.5), 3 + b]),  # the floor
        np.column_stack([a, b, np.full_like(a, -2.0)]),  # behind every camera
    ])  # fmt: skip
    texture = cv2.GaussianBlur(rng.uniform(0, 255, (120, 160)).astype(np.float32), (0, 0), 3)
    texture = 255 * (texture - texture.min()) / np.ptp(texture)
    frames = []
    for k in range(6):
        gain, offset = 0.7 + 0.05 * k, 10 * k
        image = np.clip(gain * np.roll(texture, 3 * k, axis=1) + offset, 0, 255).astype(np.uint8)
        turn = Rotation.from_euler("y", 4 * k - 10, degrees=True).as_matrix()
        in_the_way = rng.uniform((-1, -1, 2), (1, 1, 4), (occluders, 3))
        frames.append(
            ConsistencyFrame(image, make_transform(turn, (0.2 * k - 0.5, 0.0, 0.1 * k)), in_the_way)
        )
    return _Problem(frames, CAMERA, world)


@pytest.mark.skipif(photo_kernel.photo_extension() is None, reason="no C++ toolchain to build the kernel")
@pytest.mark.parametrize("blur", [4.0, 1.0])
def test_the_compiled_sums_are_the_numpy_sums(blur: float, monkeypatch: pytest.MonkeyPatch) -> None:
    problem = _room_problem()
    problem.blur(blur)
    frames = np.arange(6)
    obs = problem.observations(np.eye(4), frames)
    assert obs.n_points > 1000
    for step in range(4):  # the start and extrinsics that move points off their images
        turn = Rotation.from_rotvec(np.deg2rad([0.5, -1.0, 2.0]) * step).as_matrix()
        T = make_transform(turn, np.array([0.03, -0.02, 0.05]) * step)
        # Each frame placed elsewhere too (a time offset moves each along its own motion).
        nudges = [
            make_transform(
                Rotation.from_rotvec([0, 0.002 * k * step, 0]).as_matrix(), (0.01 * k * step, 0, 0)
            )
            for k in range(len(problem.poses))
        ]
        moves = obs.transforms(T, problem.poses @ np.stack(nudges))
        total, square, count = problem.point_sums(moves, obs)
        k_total, k_square, k_count = problem.kernel_point_sums(photo_kernel.photo_extension(), moves, obs)
        np.testing.assert_array_equal(k_count, count)
        assert (count < obs.point_counts).any() == (step > 0)
        # OpenCV's bilinear samples are at 1/32 px, the kernel's exact: the sums of up to six
        # standardised grey levels (scale 1) agree to ~3e-5.
        np.testing.assert_allclose(k_total, total, atol=2e-4)
        np.testing.assert_allclose(k_square, square, atol=1e-3)
        kernel_cost = problem.cost(T, obs)
        with monkeypatch.context() as numpy_only:
            numpy_only.setattr(photo_consistency, "photo_extension", lambda: None)
            assert kernel_cost == pytest.approx(problem.cost(T, obs), rel=1e-4)


@pytest.mark.skipif(photo_kernel.photo_extension() is None, reason="no C++ toolchain to build the kernel")
def test_the_sampling_order_and_the_threads_change_the_speed_not_the_sums() -> None:
    problem = _room_problem()
    problem.blur(1.0)
    frames = np.arange(6)
    obs = problem.observations(np.eye(4), frames)
    identity = np.arange(len(obs.point))
    assert not np.array_equal(obs.sampled, identity)  # sorted by where the points fall
    T = make_transform(Rotation.from_rotvec(np.deg2rad([0.5, -1.0, 2.0])).as_matrix(), (0.03, -0.02, 0.05))
    moves = obs.transforms(T)
    extension = photo_kernel.photo_extension()
    sums = problem.kernel_point_sums(extension, moves, obs)
    row = obs.run_frames[obs.run]

    def sampled_in(order: np.ndarray) -> photo_consistency._Observations:
        return photo_consistency._Observations(
            obs.xyz, row, obs.point, obs.n_points, problem.height, frames, obs.poses, sampled=order
        )

    shuffled = np.concatenate([
        start + np.random.default_rng(7).permutation(length)
        for start, length in zip(obs.run_starts, obs.run_lengths, strict=True)
    ])  # fmt: skip
    crossing = identity.copy()
    crossing[[0, -1]] = crossing[[-1, 0]]  # two observations swapped between the first and last run
    for threads in (1, 2, 3, 10):  # more threads than frames too
        problem.threads = threads
        for order in (identity, shuffled):
            again = problem.kernel_point_sums(extension, moves, sampled_in(order))
            for mine, theirs in zip(again, sums, strict=True):
                np.testing.assert_array_equal(mine, theirs)
        # Found in whichever thread samples the last run, and raised here.
        with pytest.raises(RuntimeError, match=r"sampled: .* outside run"):
            problem.kernel_point_sums(extension, moves, sampled_in(crossing))


@pytest.mark.skipif(photo_kernel.photo_extension() is None, reason="no C++ toolchain to build the kernel")
def test_the_compiled_visibility_is_the_numpy_visibility(monkeypatch: pytest.MonkeyPatch) -> None:
    problem = _room_problem(occluders=400)
    for step in range(4):  # extrinsics that move points off the images and behind the cameras
        turn = Rotation.from_rotvec(np.deg2rad([2.0, -4.0, 3.0]) * step).as_matrix()
        T = make_transform(turn, np.array([0.1, -0.2, 0.3]) * step)
        with monkeypatch.context() as numpy_only:
            numpy_only.setattr(photo_consistency, "photo_extension", lambda: None)
            expected = problem.visible(T)
            without_occluders = _room_problem().visible(T)
        assert expected.any()
        assert (without_occluders & ~expected).any()  # the occluders hide map points
        for threads in (1, 2, 3, 10):  # more threads than frames too
            problem.threads = threads
            np.testing.assert_array_equal(problem.visible(T), expected)


@pytest.mark.skipif(photo_kernel.photo_extension() is None, reason="no C++ toolchain to build the kernel")
def test_the_compiled_visibility_rounds_and_crops_as_numpy() -> None:
    """Points on a half pixel (rounded to even), on the image's edges (the window cut short), on
    the 5 cm near limit and just behind a nearer point's tolerance."""
    problem = _room_problem()
    n = problem.n_map
    rng = np.random.default_rng(5)
    cameras = []
    for _ in range(3):
        z = rng.choice(np.float32([0.05, 1, 2, 4, 8, 100]), n).astype(np.float32)
        u = rng.choice(np.arange(-1, 161, 0.5, dtype=np.float32), n)  # the image spans 0-159 x 0-119
        v = rng.choice(np.arange(-1, 121, 0.5, dtype=np.float32), n)
        fx, fy, cx, cy = 100.0, 100.0, 80.0, 60.0
        camera = np.stack([(u - cx) * z / fx, (v - cy) * z / fy, z]).astype(np.float32)
        camera[2, ::7] *= np.float32(1.03)  # a step behind the same pixel's nearer points
        cameras.append(np.ascontiguousarray(np.hstack([camera, camera[:, :40] * 0.5])))  # and occluders
    mask = problem.kernel_visible(photo_kernel.photo_extension(), cameras)
    for camera, shown in zip(cameras, mask, strict=True):
        expected = photo_consistency._shown_points(camera, problem.K, problem.width, problem.height)
        np.testing.assert_array_equal(np.flatnonzero(shown), expected[expected < n])
        assert 0 < shown.sum() < n


def test_the_numpy_sums_stand_in_without_a_compiler(monkeypatch: pytest.MonkeyPatch, tmp_path: Path) -> None:
    monkeypatch.setenv("LTS_CACHE_DIR", str(tmp_path))  # nothing built there yet
    monkeypatch.setenv("CXX", "no-such-compiler")
    assert photo_kernel.photo_extension.__wrapped__() is None
    monkeypatch.setattr(photo_consistency, "photo_extension", lambda: None)
    problem = _room_problem()
    obs = problem.observations(np.eye(4), np.arange(6))
    spread, between = problem.spreads(np.eye(4), obs)
    total, square, count = problem.point_sums(obs.transforms(np.eye(4)), obs)
    good = count >= photo_consistency.MIN_VIEWS
    mean, mean_square = total[good] / count[good], square[good] / count[good]
    np.testing.assert_array_equal(spread, np.maximum(mean_square - mean**2, 0))
    assert 0 < between < 2 and problem.cost(np.eye(4), obs) > 0


def test_a_wheel_carries_the_kernel_sources() -> None:
    pyproject = tomllib.loads((Path(__file__).parents[2] / "pyproject.toml").read_text())
    patterns = pyproject["tool"]["setuptools"]["package-data"]["calib"]
    package = photo_kernel.SOURCES[0].parents[1]
    carried = {path for pattern in patterns for path in package.glob(pattern)}
    assert set(photo_kernel.SOURCES + photo_kernel.HEADERS) <= carried
