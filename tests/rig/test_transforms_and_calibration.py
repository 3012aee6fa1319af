from pathlib import Path

import numpy as np
import pytest
import yaml
from scipy.spatial.transform import Rotation

from rig import (
    Calibration,
    CameraModel,
    InputError,
    check_rigid,
    distance_and_angle,
    from_quaternion,
    invert,
    load_calibration,
    make_transform,
    save_calibration,
    to_quaternion,
    transform_points,
)


def random_transforms(n: int, seed: int = 0) -> np.ndarray:
    rng = np.random.default_rng(seed)
    return make_transform(Rotation.random(n, random_state=seed).as_matrix(), rng.normal(size=(n, 3)))


def test_distance_and_angle_between_poses() -> None:
    T = random_transforms(4)
    turn = make_transform(Rotation.from_rotvec([0.0, 0.2, 0.0]).as_matrix(), [0.3, 0.0, 0.4])
    distance, angle = distance_and_angle(T @ turn, T)  # each moved by the same body-frame motion
    np.testing.assert_allclose(distance, 0.5, atol=1e-12)
    np.testing.assert_allclose(angle, 0.2, atol=1e-12)
    single = distance_and_angle(T[0], T[1])
    assert np.shape(single[0]) == np.shape(single[1]) == ()
    assert float(single[0]) == pytest.approx(np.linalg.norm(T[0, :3, 3] - T[1, :3, 3]))
    # Symmetric, and zero for a pose and itself.
    np.testing.assert_allclose(distance_and_angle(T[1], T[0]), single, atol=1e-12)
    np.testing.assert_allclose(distance_and_angle(T, T), np.zeros((2, 4)), atol=1e-7)


def test_inverse_composes_to_identity() -> None:
    T = random_transforms(5)
    np.testing.assert_allclose(invert(T) @ T, np.broadcast_to(np.eye(4), T.shape), atol=1e-12)


def test_transform_points_matches_homogeneous_product() -> None:
    T = random_transforms(1)[0]
    points = np.random.default_rng(1).normal(size=(10, 3))
    homogeneous = (T @ np.c_[points, np.ones(10)].T).T[:, :3]
    np.testing.assert_allclose(transform_points(T, points), homogeneous, atol=1e-12)


def test_quaternion_round_trip() -> None:
    T = random_transforms(7)
    q = to_quaternion(T)
    assert (q[:, 3] >= 0).all()
    np.testing.assert_allclose(from_quaternion(q, T[:, :3, 3]), T, atol=1e-12)


def test_check_rigid_rejects_non_orthonormal_rotation() -> None:
    T = np.eye(4)
    T[0, 0] = 1.01
    with pytest.raises(InputError, match="not orthonormal") as info:
        check_rigid(T, field="T_cam_lidar", path="calib.yaml")
    assert str(info.value).startswith("calib.yaml: T_cam_lidar: ")
    mirror = np.diag([1.0, 1.0, -1.0, 1.0])
    with pytest.raises(InputError, match="det"):
        check_rigid(mirror, field="T")


def make_calibration() -> Calibration:
    camera = CameraModel(
        "pinhole", 320, 240, [[300, 0, 160], [0, 300, 120], [0, 0, 1]], [0.01, -0.02, 0, 0, 0]
    )
    return Calibration(camera, random_transforms(1)[0], 0.0125, {"rms_px": 0.21})


def test_calibration_file_round_trip(tmp_path: Path) -> None:
    calibration = make_calibration()
    save_calibration(calibration, tmp_path / "calib.yaml")
    again = load_calibration(tmp_path / "calib.yaml")
    np.testing.assert_array_equal(again.T_cam_lidar, calibration.T_cam_lidar)
    np.testing.assert_array_equal(again.camera.K, calibration.camera.K)
    assert again.time_offset_s == 0.0125 and again.quality == {"rms_px": 0.21}


def test_a_file_with_the_camera_alone_says_it_has_no_extrinsic(tmp_path: Path) -> None:
    """``lts calibrate intrinsics`` writes the camera alone: no identity extrinsic to mistake for a
    guess, and where one is needed the error names the field."""
    camera_only = make_calibration()
    camera_only.has_extrinsic = False
    path = tmp_path / "cam.yaml"
    save_calibration(camera_only, path)
    assert "T_cam_lidar" not in yaml.safe_load(path.read_text())
    again = load_calibration(path)
    assert not again.has_extrinsic and again.time_offset_s == 0.0125
    assert load_calibration(tmp_path / "cam.yaml").camera.width == 320
    with pytest.raises(InputError) as info:
        load_calibration(path, needs_extrinsic=True)
    assert info.value.field == "T_cam_lidar" and str(info.value).startswith(f"{path}: T_cam_lidar: missing")
    save_calibration(make_calibration(), path)
    assert load_calibration(path, needs_extrinsic=True).has_extrinsic


@pytest.mark.parametrize(
    ("edit", "field"),
    [
        (
            lambda d: d.update(T_cam_lidar=[[1, 0, 0, 0], [0, 2, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1]]),
            "T_cam_lidar",
        ),
        (lambda d: d.update(T_cam_lidar=[[1, 0, 0], [0, 1, 0], [0, 0, 1]]), "T_cam_lidar"),
        (lambda d: d.update(time_offset_s="soon"), "time_offset_s"),
        (lambda d: d["camera"].update(K=[[300, 0, 160], [0, -300, 120], [0, 0, 1]]), "camera.K"),
        (lambda d: d.pop("camera"), "camera"),
    ],
)
def test_bad_calibration_file_names_file_and_field(tmp_path: Path, edit, field: str) -> None:
    data = make_calibration().to_dict()
    edit(data)
    path = tmp_path / "calib.yaml"
    path.write_text(yaml.safe_dump(data))
    with pytest.raises(InputError) as info:
        load_calibration(path)
    assert info.value.field == field
    assert str(info.value).startswith(f"{path}: {field}: ")
