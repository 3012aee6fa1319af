"""Targetless extrinsic refinement: degenerate input and the real PJLab LiDAR + camera pairs."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from calib.kitti_frames import read_kitti_frame
from calib.pjlab_pairs import read_pjlab_pair
from calib.targetless import ExtrinsicPair, refine_extrinsic
from rig.camera import CameraModel
from rig.pointcloud_io import PointCloud
from rig.transforms import distance_and_angle


def load_pjlab(root: Path, name: str) -> tuple[ExtrinsicPair, CameraModel, np.ndarray]:
    """Image + cloud, camera model and reference ``T_cam_lidar`` of one shared PJLab pair."""
    return read_pjlab_pair(root / "lidar_camera_pjlab", name)


def perturb(T: np.ndarray, rng: np.random.Generator, deg: float = 2.0, metres: float = 0.10) -> np.ndarray:
    """``T`` with its rotation turned by ``deg`` about a random axis and ``metres`` added to its
    translation in a random direction."""
    axis, shift = rng.normal(size=3), rng.normal(size=3)
    out = T.copy()
    out[:3, :3] = Rotation.from_rotvec(np.radians(deg) * axis / np.linalg.norm(axis)).as_matrix() @ T[:3, :3]
    out[:3, 3] += metres * shift / np.linalg.norm(shift)
    return out


def test_empty_scan_is_poorly_constrained() -> None:
    camera = CameraModel(
        "pinhole", 320, 240, np.array([[250.0, 0, 160], [0, 250, 120], [0, 0, 1]]), np.zeros(0)
    )
    image = np.random.default_rng(0).integers(0, 255, (240, 320, 3), dtype=np.uint8)
    T = np.eye(4)
    result = refine_extrinsic(
        [ExtrinsicPair(image, PointCloud(np.zeros((0, 3)), np.zeros(0, np.float32)))], camera, T
    )
    assert result.verdict == "poorly constrained"
    assert "only 0 LiDAR points" in result.reasons[0]
    np.testing.assert_array_equal(result.T_cam_lidar, T)


def test_points_behind_the_camera_are_poorly_constrained() -> None:
    camera = CameraModel(
        "pinhole", 320, 240, np.array([[250.0, 0, 160], [0, 250, 120], [0, 0, 1]]), np.zeros(0)
    )
    image = np.zeros((240, 320), np.uint8)
    behind = np.random.default_rng(0).uniform(-5, 5, (5000, 3)) - [0, 0, 10]
    result = refine_extrinsic(
        [ExtrinsicPair(image, PointCloud(behind, np.ones(5000, np.float32)))], camera, np.eye(4)
    )
    assert result.verdict == "poorly constrained"


def _check_pair(real_data: Path, name: str, seed: int) -> None:
    pair, camera, T_ref = load_pjlab(real_data, name)
    T_init = perturb(T_ref, np.random.default_rng(seed))
    result = refine_extrinsic([pair], camera, T_init)
    _, angle = distance_and_angle(result.T_cam_lidar, T_ref)
    rot = np.degrees(angle)
    # Measured: 0.07–0.49° on seeds 1–5 (README, calibration section). One frame of far structure
    # does not place the LiDAR to centimetres: the refinement must say so and keep the guess's
    # translation instead of drifting.
    assert rot < 0.6, rot
    np.testing.assert_allclose(result.T_cam_lidar[:3, 3], T_init[:3, 3])
    assert result.verdict == "poorly constrained"
    assert any("translation not observable" in r for r in result.reasons)
    assert result.mutual_information["final"] > result.mutual_information["init"]


def load_kitti(root: Path, frames: list[int]) -> tuple[list[ExtrinsicPair], CameraModel, np.ndarray]:
    """Image + Velodyne pairs of KITTI frames sharing one calibration, the rectified left colour
    camera and its reference ``T_cam_velo``."""
    read = [read_kitti_frame(root / "kitti_frames", f"{frame:06d}") for frame in frames]
    return [pair for pair, _, _ in read], read[0][1], read[0][2]


@pytest.mark.slow
@pytest.mark.parametrize("frames", [[0], [1, 2]])
def test_kitti_result_is_never_confidently_wrong(real_data, frames: list[int]) -> None:
    """KITTI's target-based reference is trustworthy, and its 64-beam scans are unlike PJLab's:
    whatever the refinement reaches, a result off the reference must not say ok."""
    pairs, camera, T_ref = load_kitti(real_data, frames)
    for seed in (1, 2, 3):
        result = refine_extrinsic(pairs, camera, perturb(T_ref, np.random.default_rng(seed)))
        trans, angle = distance_and_angle(result.T_cam_lidar, T_ref)
        rot = np.degrees(angle)
        if rot > 0.3 or trans > 0.03:
            assert result.verdict == "poorly constrained", (seed, rot, trans)
            assert result.reasons


def test_real_pjlab_auto_pair(real_data) -> None:
    _check_pair(real_data, "auto", seed=11)


@pytest.mark.slow
@pytest.mark.parametrize("name", ["manual", "auto"])
@pytest.mark.parametrize("seed", [1, 2, 3])
def test_real_pjlab_pairs_several_perturbations(real_data, name: str, seed: int) -> None:
    _check_pair(real_data, name, seed)
