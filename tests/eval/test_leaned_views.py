import numpy as np
import pytest
import trimesh

from eval.leaned_views import leaned_poses, mesh_hole_fraction
from rig import CameraModel, make_transform

CAMERA = CameraModel("pinhole", 64, 48, [[40, 0, 31.5], [0, 40, 23.5], [0, 0, 1]], [])


def room() -> trimesh.Trimesh:
    box = trimesh.creation.box(extents=[6.0, 4.0, 2.5])
    box.invert()
    return box


def looking_along_x(x: float) -> np.ndarray:
    """A camera at (x, 0, 0) looking along +x (camera z), y down (world -z)."""
    R_world_cam = np.array([[0, 0, 1], [-1, 0, 0], [0, -1, 0]], dtype=float)
    return make_transform(R_world_cam, [x, 0.0, 0.0])


def test_leaned_poses_turn_and_shift_each_pose() -> None:
    pose = looking_along_x(0.0)
    leaned = leaned_poses(pose[None], yaw_deg=10.0, shift_m=0.2)
    assert leaned.shape == (4, 4, 4)
    forward = leaned[:2, :3, 2]
    angles = np.degrees(np.arccos(forward @ pose[:3, 2]))
    np.testing.assert_allclose(angles, [10.0, 10.0], atol=1e-9)
    np.testing.assert_allclose(np.linalg.norm(leaned[2:, :3, 3] - pose[:3, 3], axis=1), 0.2, atol=1e-12)
    np.testing.assert_allclose(leaned[2:, :3, :3], np.stack([pose[:3, :3]] * 2))


def test_the_ground_truth_itself_has_no_holes() -> None:
    poses = leaned_poses(np.stack([looking_along_x(x) for x in (-1.0, 0.0)]))
    result = mesh_hole_fraction(room(), room(), CAMERA, poses)
    assert result.hole_fraction == 0.0 and result.holes.shape == (8, 48, 64)


def test_a_missing_wall_shows_as_holes_where_it_is_seen() -> None:
    full = room()
    centres = full.triangles_center
    without_far_wall = trimesh.Trimesh(full.vertices, full.faces[centres[:, 0] < 2.9], process=False)
    facing = mesh_hole_fraction(without_far_wall, full, CAMERA, looking_along_x(0.0)[None])
    assert facing.hole_fraction > 0.3  # the far wall fills much of the view
    away = looking_along_x(0.0) @ make_transform(np.diag([-1.0, 1.0, -1.0]), np.zeros(3))  # turned round
    assert mesh_hole_fraction(without_far_wall, full, CAMERA, away[None]).hole_fraction == pytest.approx(0.0)
