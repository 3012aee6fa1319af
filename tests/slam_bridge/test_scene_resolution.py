"""Scenes at a lower resolution than the recording's (``lts prepare --max-size / --downscale``)."""

from pathlib import Path

import cv2
import numpy as np
import pytest

from rig import CameraModel, InputError, load_calibration
from slam_bridge.keyframe_normals import undistort_normals
from slam_bridge.prepare_config import DEFAULT_MAX_SIZE, PrepareConfig
from slam_bridge.scene import load_scene, write_scene_index
from slam_bridge.scene_builder import build_scene
from tests.slam_bridge.test_scene_builder import ground_truth_depth


def sim_camera(width: int, height: int) -> CameraModel:
    """The virtual rig's pinhole camera at ``width`` x ``height`` (``rig.sim.config.SimConfig.camera``)."""
    from rig.sim.config import SimConfig

    return SimConfig(width=width, height=height).camera()


@pytest.fixture(scope="module")
def scenes(
    quick_room: Path, gt_slam_dir: Path, tmp_path_factory: pytest.TempPathFactory
) -> tuple[Path, Path]:
    """The quick room (160x120) prepared at full size and with ``--downscale 2`` (80x60)."""
    calibration = load_calibration(quick_room / "ground_truth" / "calib.yaml")
    full, half = tmp_path_factory.mktemp("full"), tmp_path_factory.mktemp("half")
    build_scene(quick_room / "session.mcap", calibration, gt_slam_dir, full, PrepareConfig(max_size=0))
    build_scene(quick_room / "session.mcap", calibration, gt_slam_dir, half, PrepareConfig(downscale=2))
    return full, half


@pytest.mark.parametrize(
    ("size", "config", "expected"),
    [
        ((1920, 1080), PrepareConfig(), (DEFAULT_MAX_SIZE, round(DEFAULT_MAX_SIZE * 1080 / 1920))),
        ((1920, 1080), PrepareConfig(max_size=0), (1920, 1080)),
        ((1920, 1080), PrepareConfig(max_size=500), (500, 281)),
        ((1920, 1080), PrepareConfig(max_size=500, downscale=4), (480, 270)),
        ((1280, 720), PrepareConfig(max_size=2000, downscale=2), (640, 360)),
        ((320, 240), PrepareConfig(), (320, 240)),
        ((160, 120), PrepareConfig(), (160, 120)),
        ((320, 240), PrepareConfig(downscale=2), (160, 120)),
    ],
)
def test_scene_camera_size(size: tuple[int, int], config: PrepareConfig, expected: tuple[int, int]) -> None:
    camera = sim_camera(*size)
    scene_camera = config.scene_camera(camera)
    assert scene_camera.size == expected and scene_camera.model == "pinhole" and not scene_camera.dist.any()
    if expected == size:  # untouched: the undistorted camera itself
        np.testing.assert_array_equal(scene_camera.K, camera.K)


@pytest.mark.parametrize(
    ("options", "field"),
    [
        ({"max_size": -1}, "max_size"),
        ({"downscale": 0}, "downscale"),
        ({"keyframe_interval_s": -1.0}, "keyframe_interval_s"),
        ({"keyframe_min_motion": (-1.0, 5.0)}, "keyframe_min_motion"),
        ({"test_every": -1}, "test_every"),
    ],
)
def test_settings_out_of_range_are_refused(options: dict, field: str) -> None:
    with pytest.raises(InputError) as refused:
        PrepareConfig(**options)
    assert refused.value.field == field


def test_small_recordings_are_untouched_by_the_default(scenes: tuple[Path, Path], quick_room: Path) -> None:
    """The default --max-size leaves the demo's 320x240 and the quick run's 160x120 as they were:
    the same camera and the same images as at full size."""
    from slam_bridge.scene_builder import DEFAULT_CONFIG

    assert DEFAULT_CONFIG.max_size >= 320
    full = load_scene(scenes[0])
    calibration = load_calibration(quick_room / "ground_truth" / "calib.yaml")
    default = DEFAULT_CONFIG.scene_camera(calibration.camera)
    assert default.size == full.camera.size == (160, 120)
    np.testing.assert_array_equal(default.K, full.camera.K)


def test_a_lidar_point_lands_at_the_same_place_in_both_scenes(scenes: tuple[Path, Path]) -> None:
    full, half = load_scene(scenes[0]), load_scene(scenes[1])
    assert half.camera.size == (80, 60) and half.options.downscale == 2
    for keyframe in half.keyframes:
        points = half.lidar(keyframe).points
        assert len(points) > 100
        at_full = (full.camera.project(points) + 0.5) / full.camera.size
        at_half = (half.camera.project(points) + 0.5) / half.camera.size
        np.testing.assert_allclose(at_half, at_full, atol=1e-6)


def test_half_size_images_are_the_full_size_images_area_averaged(scenes: tuple[Path, Path]) -> None:
    """At a whole factor, undistorting into the smaller camera samples the full-size undistortion's
    pixels and averages each 2x2 block of them: one bilinear resampling, not two."""
    full, half = load_scene(scenes[0]), load_scene(scenes[1])
    for keyframe in half.keyframes:
        averaged = cv2.resize(full.image(keyframe), half.camera.size, interpolation=cv2.INTER_AREA)
        np.testing.assert_array_equal(half.image(keyframe), averaged)


def test_half_size_depth_keeps_the_nearest_return_per_pixel(
    scenes: tuple[Path, Path], quick_room: Path
) -> None:
    """Depth is z-buffered from the points at the scene's own size: every value is a LiDAR return's
    z (no blend of foreground and background) and agrees with the true surface."""
    half = load_scene(scenes[1])
    errors = []
    for keyframe in half.keyframes:
        lidar = half.lidar(keyframe)
        depth = half.depth(keyframe)
        assert np.isin(depth[depth > 0], lidar.points[:, 2]).all()
        truth = ground_truth_depth(
            quick_room / "ground_truth" / "mesh.ply", half.camera, keyframe.T_world_cam
        )
        valid = depth > 0
        assert valid.mean() > 0.1  # the sweeps between neighbours 0.2 s away: ~15 % of the pixels
        errors.append(np.abs(depth[valid] - truth[valid]))
    errors = np.concatenate(errors)
    assert np.median(errors) < 0.02
    # 3.4 % (0.3 % at full size): a pixel that straddles an edge holds its nearest return, while the
    # truth is cast through its centre
    assert np.mean(errors > 0.10) < 0.05


def test_half_size_normals_are_unit_or_none(scenes: tuple[Path, Path]) -> None:
    full, half = load_scene(scenes[0]), load_scene(scenes[1])
    for keyframe in half.keyframes:
        normals = half.normals(keyframe)
        assert normals.shape == (60, 80, 3)
        length = np.linalg.norm(normals, axis=-1)
        assert np.all((length == 0) | (np.abs(length - 1) < 1e-4))
        agree = np.einsum("ijk,ijk->ij", normals, full.normals(keyframe)[::2, ::2])
        assert np.mean(agree[length > 0] > 0.99) > 0.9  # the mesh's faces, seen through the same rays


def test_given_normal_maps_are_resized_by_nearest_pixel_and_keep_their_holes() -> None:
    camera = sim_camera(320, 240)
    target = PrepareConfig(max_size=100).scene_camera(camera)
    normals = np.zeros((240, 320, 3), np.float32)
    normals[:, :160] = [0.0, 0.0, -2.0]  # left half: facing the camera, not unit length
    normals[:, 160:200] = [0.6, 0.0, -0.8]  # a strip of another direction; the right part: none
    out = undistort_normals(normals, camera, target)
    assert out.shape == (75, 100, 3)
    length = np.linalg.norm(out, axis=-1)
    assert set(np.unique(np.round(length, 5))) <= {0.0, 1.0}
    unit = out[length > 0]
    assert np.all(
        np.isclose(unit, [0, 0, -1], atol=1e-6).all(axis=1) | np.isclose(unit, [0.6, 0, -0.8]).all(axis=1)
    )
    row = out[37]
    assert np.allclose(row[10:45], [0, 0, -1]) and np.allclose(row[52:60], [0.6, 0, -0.8])
    assert not row[66:90].any()  # no normal stays no normal


def test_resolution_options_round_trip_through_scene_json(tmp_path: Path) -> None:
    config = PrepareConfig(max_size=1000, downscale=3)
    camera = config.scene_camera(sim_camera(1920, 1080))
    from slam_bridge.scene import Keyframe

    write_scene_index(tmp_path, camera, [Keyframe("a", 1, np.eye(4), "train")], config, {})
    scene = load_scene(tmp_path)
    assert scene.options == config and scene.camera.size == (640, 360)
    np.testing.assert_allclose(scene.camera.K, camera.K)


@pytest.mark.parametrize(
    ("field", "value"), [("max_size", -1), ("max_size", 1.5), ("downscale", 0), ("downscale", "2")]
)
def test_bad_resolution_options_are_refused(tmp_path: Path, field: str, value) -> None:
    with pytest.raises(InputError, match=field):
        PrepareConfig(**{field: value})
    from slam_bridge.scene import Keyframe

    write_scene_index(
        tmp_path,
        sim_camera(32, 24).undistorted(),
        [Keyframe("a", 1, np.eye(4), "train")],
        PrepareConfig(),
        {},
    )
    import json

    data = json.loads((tmp_path / "scene.json").read_text())
    data["options"][field] = value
    (tmp_path / "scene.json").write_text(json.dumps(data))
    with pytest.raises(InputError, match=rf"scene.json: options\.{field}: expected a whole number"):
        load_scene(tmp_path)


@pytest.mark.parametrize(
    ("option", "value", "says"),
    [("--max-size", "-1", "greater than or equal to 0"), ("--max-size", "600.5", "valid integer"),
     ("--downscale", "0", "greater than or equal to 1"), ("--downscale", "1.5", "valid integer")],
)  # fmt: skip
@pytest.mark.parametrize("command", ["prepare", "reconstruct"])
def test_cli_refuses_a_bad_resolution_in_one_line(
    lts_cli, tmp_path: Path, command: str, option: str, value: str, says: str
) -> None:
    args = ["--calib", tmp_path / "c.yaml", "--out", tmp_path / "out"]
    args += ["--slam", tmp_path / "slam"] if command == "prepare" else []
    code, out, err = lts_cli(command, tmp_path / "s.mcap", *args, option, value)
    assert code == 2 and out == ""
    usage, _, error = err.strip().splitlines()  # Click's short usage, where to get help, the error
    assert usage.startswith(f"Usage: lts {command}") and option in error and says in error
