"""The calibration a bag carries: T_cam_lidar composed along /tf_static, the camera from CameraInfo."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from bag_layouts import LAYOUTS
from scipy.spatial.transform import Rotation

from rig.calibration import load_calibration
from rig.errors import InputError
from rig.session import find_topics, open_recording
from rig.session.tf_static import lookup, recording_calibration, tf_extrinsic
from rig.transforms import invert, make_transform
from tests.session.ros1_bags import cloud, image, write_ros1_bag


def _pose(seed: int) -> np.ndarray:
    rng = np.random.default_rng(seed)
    return make_transform(Rotation.random(random_state=seed).as_matrix(), rng.normal(size=3))


def test_lookup_composes_along_the_tree_both_ways() -> None:
    base_lidar, base_camera, camera_optical = _pose(1), _pose(2), _pose(3)
    edges = {
        ("base", "lidar"): base_lidar,
        ("base", "camera"): base_camera,
        ("camera", "optical"): camera_optical,
    }
    T = lookup(edges, "optical", "lidar")
    np.testing.assert_allclose(T, invert(base_camera @ camera_optical) @ base_lidar, atol=1e-12)
    np.testing.assert_allclose(lookup(edges, "lidar", "optical"), invert(T), atol=1e-12)
    np.testing.assert_allclose(lookup(edges, "lidar", "lidar"), np.eye(4))
    assert lookup(edges, "optical", "elsewhere") is None


@pytest.mark.parametrize("layout", sorted(LAYOUTS))
def test_every_layout_carries_the_true_extrinsic(
    layout: str, layout_bags: dict, virtual_rig_scene: Path
) -> None:
    truth = load_calibration(virtual_rig_scene / "ground_truth" / "calib.yaml")
    recording = open_recording(layout_bags[layout])
    topics = find_topics(recording)
    extrinsic = tf_extrinsic(recording, topics)
    assert extrinsic is not None and extrinsic.lidar_frame == LAYOUTS[layout].frame_ids["lidar"]
    np.testing.assert_allclose(extrinsic.T_cam_lidar, truth.T_cam_lidar, atol=1e-9)
    calibration = recording_calibration(recording, topics)
    assert calibration.camera.size == truth.camera.size and calibration.time_offset_s == 0.0
    np.testing.assert_allclose(calibration.camera.K, truth.camera.K)
    assert "/tf_static" in calibration.quality["source"]


def test_a_bag_without_tf_static_says_what_is_missing(tmp_path: Path) -> None:
    bag = write_ros1_bag(tmp_path / "plain.bag", [("/cam", 10, image(5)), ("/points", 20, cloud(15))])
    recording = open_recording(bag)
    topics = find_topics(recording)
    assert tf_extrinsic(recording, topics) is None
    with pytest.raises(InputError, match="no CameraInfo topic, which --calib tf needs"):
        recording_calibration(recording, topics)
