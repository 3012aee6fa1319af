"""Others' bags of a virtual-rig session prepare the scene the session itself prepares, and a split
ROS 1 bag reconstructs end to end with its own calibration (CameraInfo + /tf_static)."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import cv2
import numpy as np
import pytest
from bag_layouts import LAYOUTS
from truth_slam import write_truth_slam

from slam_bridge.scene import load_scene

LTS = Path(sys.executable).parent / "lts"
#: Layouts whose images are stored as JPEG again (the session's own images are JPEG already).
JPEG_LAYOUTS = ("utmm", "utmm_split", "velodyne_ros2_mcap")


def prepare(recording: Path, truth: Path, slam: Path, out: Path) -> Path:
    args = [LTS, "prepare", recording, "--calib", truth / "calib.yaml", "--slam", slam, "--out", out]
    result = subprocess.run(args, capture_output=True, text=True, timeout=300)
    assert result.returncode == 0, result.stderr[-2000:]
    return out


@pytest.fixture(scope="module")
def truth_slam(virtual_rig_scene: Path, tmp_path_factory: pytest.TempPathFactory) -> Path:
    return write_truth_slam(virtual_rig_scene, tmp_path_factory.mktemp("truth_slam"))


@pytest.fixture(scope="module")
def native_scene(virtual_rig_scene: Path, truth_slam: Path, tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("native") / "scene"
    return prepare(virtual_rig_scene / "session.mcap", virtual_rig_scene / "ground_truth", truth_slam, out)


@pytest.mark.parametrize("layout", sorted(LAYOUTS))
def test_a_bag_prepares_the_scene_of_its_session(
    layout: str,
    layout_bags: dict,
    virtual_rig_scene: Path,
    truth_slam: Path,
    native_scene: Path,
    tmp_path: Path,
) -> None:
    scene_dir = prepare(
        layout_bags[layout], virtual_rig_scene / "ground_truth", truth_slam, tmp_path / "scene"
    )
    got, want = load_scene(scene_dir), load_scene(native_scene)
    assert [(k.name, k.t_ns, k.split) for k in got.keyframes] == [
        (k.name, k.t_ns, k.split) for k in want.keyframes
    ]
    for mine, native in zip(got.keyframes, want.keyframes, strict=True):
        np.testing.assert_allclose(mine.T_world_cam, native.T_world_cam, rtol=0, atol=1e-9)
        points = np.load(scene_dir / "lidar" / f"{mine.name}.npy")
        np.testing.assert_allclose(points, np.load(native_scene / "lidar" / f"{native.name}.npy"), atol=1e-5)
        image = cv2.imread(str(scene_dir / "images" / f"{mine.name}.png"), cv2.IMREAD_UNCHANGED).astype(int)
        expected = cv2.imread(str(native_scene / "images" / f"{native.name}.png"), cv2.IMREAD_UNCHANGED)
        if layout == "newer_college":  # a grey camera: the grey of the same pixels
            expected = cv2.cvtColor(expected, cv2.COLOR_BGR2GRAY)
        difference = np.abs(image - expected.astype(int))
        if layout in JPEG_LAYOUTS:
            assert difference.mean() < 4.0  # a second JPEG generation at quality 95
        else:
            assert difference.max() <= 1  # undistortion rounding only


@pytest.mark.slow
def test_split_bags_reconstruct_with_their_own_calibration(
    layout_bags: dict, virtual_rig_scene: Path, tmp_path: Path
) -> None:
    run = tmp_path / "run"
    args = [
        LTS, "reconstruct", layout_bags["utmm_split"], "--calib", "tf", "--topics", "ut-mm",
        "--gt", virtual_rig_scene / "ground_truth", "--preset", "fast", "--iterations", "150",
        "--keyframe-interval", "0.2", "--out", run, "--json",
    ]  # fmt: skip
    result = subprocess.run(args, capture_output=True, text=True, timeout=900)
    assert result.returncode == 0, result.stderr[-3000:]
    metrics = json.loads(result.stdout)
    assert (run / "train" / "mesh.ply").is_file()
    assert metrics["fscore"] > 0.6 and metrics["psnr"] > 14.0
