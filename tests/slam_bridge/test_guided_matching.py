"""Guided matching keeps the matches the known geometry allows, and only those."""

import numpy as np
import trimesh

from rig.camera import CameraModel
from rig.mesh_rays import mesh_raycaster
from rig.transforms import invert, make_transform, transform_points
from slam_bridge.guided_matching import KeyframeFeatures, guided_matches
from slam_bridge.keyframe_pairs import (
    MAX_PARTNERS,
    MAX_SCALE_CHANGE,
    TIME_NEIGHBOURS,
    comparable_scales,
    keyframe_pairs,
)

CAMERA = CameraModel("pinhole", 640, 480, [[500, 0, 319.5], [0, 500, 239.5], [0, 0, 1]], [])
RNG_SEED = 0


def looking_along_z(position: np.ndarray, yaw_deg: float = 0.0) -> np.ndarray:
    """``T_world_cam`` of a camera at ``position`` looking along +z, turned by ``yaw`` about y."""
    c, s = np.cos(np.radians(yaw_deg)), np.sin(np.radians(yaw_deg))
    return make_transform(np.array([[c, 0, s], [0, 1, 0], [-s, 0, c]]), position)


def features(points: np.ndarray, descriptors: np.ndarray, pose: np.ndarray, depth: bool) -> KeyframeFeatures:
    """What a keyframe at ``pose`` sees of world ``points`` ``(N, 3)`` with these descriptors."""
    local = transform_points(invert(pose), points)
    uv = CAMERA.project(local)
    z = local[:, 2] if depth else np.full(len(points), np.nan)
    return KeyframeFeatures(uv, descriptors.astype(np.float32), z, pose)


def scene(count: int = 300) -> tuple[np.ndarray, np.ndarray]:
    """Points 5-8 m ahead and SIFT-like descriptors (non-negative, length 512, integer, as COLMAP's)."""
    rng = np.random.default_rng(RNG_SEED)
    points = np.column_stack([rng.uniform(-3, 3, count), rng.uniform(-2, 2, count), rng.uniform(5, 8, count)])
    descriptors = rng.gamma(0.5, size=(count, 128))
    return points, np.round(
        np.minimum(512 * descriptors / np.linalg.norm(descriptors, axis=1, keepdims=True), 255)
    )


def test_true_correspondences_are_found_on_a_moving_camera() -> None:
    points, descriptors = scene()
    a = features(points, descriptors, looking_along_z(np.zeros(3)), depth=True)
    b = features(points, descriptors, looking_along_z(np.array([0.4, 0.0, 0.3]), yaw_deg=5.0), depth=True)
    matches = guided_matches(a, b, CAMERA)
    assert len(matches) == len(points)
    np.testing.assert_array_equal(matches[:, 0], matches[:, 1])


def test_a_twin_off_the_geometry_is_not_matched() -> None:
    """Repeated texture: B sees each descriptor 40 px away from where the point is, along the
    epipolar line or across it. Across it the line rules it out; along it, only the depth does."""
    points, descriptors = scene()
    a_pose, b_pose = looking_along_z(np.zeros(3)), looking_along_z(np.array([0.5, 0.0, 0.0]))
    b = features(points, descriptors, b_pose, depth=True)
    for shift in ([40.0, 0.0], [0.0, 40.0]):  # the baseline is along x: epipolar lines are rows
        twin_b = KeyframeFeatures(b.uv + np.array(shift), b.descriptors, b.depth, b_pose)
        for depth in (True, False):
            matches = guided_matches(features(points, descriptors, a_pose, depth), twin_b, CAMERA)
            allowed_by_the_line_alone = shift[0] and not depth
            assert len(matches) == (len(points) if allowed_by_the_line_alone else 0)


def with_copies(seen: KeyframeFeatures) -> KeyframeFeatures:
    """``seen`` with a copy of every keypoint 40 px below it (same descriptor, no depth)."""
    return KeyframeFeatures(
        np.concatenate([seen.uv, seen.uv + np.array([0.0, 40.0])]),
        np.concatenate([seen.descriptors] * 2),
        np.concatenate([seen.depth, np.full(len(seen.depth), np.nan)]),
        seen.T_world_cam,
    )


def test_an_ambiguous_descriptor_is_not_matched() -> None:
    """Lowe's ratio test is over the whole of both images: a copy elsewhere in either one makes a
    match ambiguous (the copies lie off the epipolar lines, so the band alone would keep them)."""
    points, descriptors = scene()
    a = features(points, descriptors, looking_along_z(np.zeros(3)), depth=True)
    b = features(points, descriptors, looking_along_z(np.array([0.5, 0.0, 0.0])), depth=True)
    assert len(guided_matches(a, b, CAMERA)) == len(points)
    assert len(guided_matches(a, with_copies(b), CAMERA)) == 0
    assert len(guided_matches(with_copies(a), b, CAMERA)) == 0


def test_poses_wrong_beyond_the_tolerance_give_no_matches() -> None:
    points, descriptors = scene()
    a = features(points, descriptors, looking_along_z(np.zeros(3)), depth=True)
    b = features(points, descriptors, looking_along_z(np.array([0.5, 0.0, 0.0])), depth=True)
    wrong = KeyframeFeatures(
        b.uv, b.descriptors, b.depth, looking_along_z(np.array([0.5, 0.0, 0.0]), yaw_deg=6.0)
    )
    assert len(guided_matches(a, wrong, CAMERA)) == 0


def test_a_camera_turning_in_place_is_matched() -> None:
    points, descriptors = scene()
    a = features(points, descriptors, looking_along_z(np.zeros(3)), depth=False)
    b = features(points, descriptors, looking_along_z(np.zeros(3), yaw_deg=10.0), depth=False)
    matches = guided_matches(a, b, CAMERA)
    assert len(matches) == len(points)
    np.testing.assert_array_equal(matches[:, 0], matches[:, 1])


def test_pairs_grow_linearly_and_a_revisit_is_paired() -> None:
    """Inside a 20 m x 20 m room, a camera goes round a 12 m loop facing outwards, and comes back."""
    room = trimesh.creation.box(extents=[20.0, 6.0, 20.0])
    room.invert()
    raycaster = mesh_raycaster(room)
    angles = np.linspace(0.0, 360.0, 41)[:-1]
    poses = np.stack(
        [
            looking_along_z(np.array([6 * np.sin(np.radians(a)), 0.0, 6 * np.cos(np.radians(a))]), a)
            for a in angles
        ]
    )
    poses = np.concatenate([poses, poses[:1]])  # the revisit
    pairs = keyframe_pairs(raycaster, CAMERA, poses)
    assert len(pairs) <= len(poses) * (MAX_PARTNERS + TIME_NEIGHBOURS)
    assert (0, len(poses) - 1) in pairs
    assert all((i, i + 1) in pairs for i in range(len(poses) - 1))
    assert (0, 20) not in pairs  # facing away from each other


def test_only_keyframes_at_comparable_distances_are_compared() -> None:
    """Keyframe 0 sees a surface 2 m ahead; keyframe 1 is 1 m behind it (1.5x the distance),
    keyframe 2 further back than the scale limit allows, keyframe 3 sees nothing."""
    back = [0.0, 1.0, 2.0 * MAX_SCALE_CHANGE, 0.0]
    poses = np.stack([looking_along_z(np.array([0.0, 0.0, -b])) for b in back])
    wall = np.column_stack([np.linspace(-1, 1, 5), np.zeros(5), np.full(5, 2.0)])
    samples = [wall, wall, wall, np.zeros((0, 3))]
    comparable = comparable_scales(poses, samples)
    np.testing.assert_array_equal(comparable[0], [True, True, False, True])
    assert not comparable[3].any()
