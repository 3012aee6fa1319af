"""Keyframe matching gives the same database and sparse points whatever the thread count, and only
geometrically consistent matches."""

import subprocess
import sys
from pathlib import Path

import numpy as np
import pycolmap
import trimesh

from rig.mesh_rays import mesh_raycaster
from slam_bridge.colmap_matches import extract_keyframe_features, match_keyframes, read_correspondences
from slam_bridge.guided_matching import REFINEMENT_TOLERANCE_DEG, tolerance_px
from slam_bridge.scene import load_scene
from slam_bridge.sparse_points import triangulate_keyframes


def test_matching_with_one_and_two_threads_gives_the_same_matches_and_points(
    quick_room: Path, gt_slam_dir: Path, tmp_path: Path
) -> None:
    lts = Path(sys.executable).parent / "lts"
    calib = quick_room / "ground_truth" / "calib.yaml"
    scene_dir = tmp_path / "scene"
    prepare = [lts, "prepare", quick_room / "session.mcap", "--calib", calib, "--slam", gt_slam_dir]
    subprocess.run([*prepare, "--out", scene_dir], check=True, capture_output=True, timeout=300)
    scene = load_scene(scene_dir)
    names = [f"{k.name}.png" for k in scene.keyframes]
    poses = np.stack([k.T_world_cam for k in scene.keyframes])
    raycaster = mesh_raycaster(trimesh.load(scene_dir / "mesh.ply", process=False))
    images = scene_dir / "images"
    databases = [
        extract_keyframe_features(images, tmp_path / f"run{t}", scene.camera, names, threads=t)
        for t in (1, 2, 2)
    ]
    reports = [
        match_keyframes(database, scene.camera, poses, raycaster, threads=t)
        for database, t in zip(databases, (1, 2, 2), strict=True)
    ]
    assert reports[0].matches > 100
    matches = [read_correspondences(database.path, names) for database in databases]
    for other in matches[1:]:
        for field in ("observer", "source", "uv_observer", "uv_source", "match"):
            np.testing.assert_array_equal(getattr(other, field), getattr(matches[0], field))
    # every match lies on its epipolar line (the poses are true)
    first = matches[0]
    T_b_a = np.linalg.inv(poses[first.observer]) @ poses[first.source]
    K_inv = np.linalg.inv(scene.camera.K)

    def homogeneous(uv: np.ndarray) -> np.ndarray:
        return np.concatenate([uv, np.ones((len(uv), 1))], axis=1)

    rays_a = np.einsum("nij,nj->ni", T_b_a[:, :3, :3], homogeneous(first.uv_source) @ K_inv.T)
    lines = np.cross(T_b_a[:, :3, 3], rays_a) @ K_inv  # in B's pixels
    distance = np.abs(np.sum(lines * homogeneous(first.uv_observer), axis=1))
    assert np.all(distance <= tolerance_px(scene.camera) * np.linalg.norm(lines[:, :2], axis=1) + 1e-6)
    points = [
        triangulate_keyframes(database.path, images, database.path.parent, scene.keyframes).points
        for database in databases[:2]
    ]
    np.testing.assert_array_equal(points[1], points[0])
    db = pycolmap.Database.open(databases[0].path)
    try:
        assert db.num_frames() == len(names)
        assert db.num_verified_image_pairs() == reports[0].matched_pairs
    finally:
        db.close()
    # matched again (as --refine-poses then --sparse-points do): the new matches replace the old
    wide = match_keyframes(
        databases[2], scene.camera, poses, raycaster, tolerance_deg=REFINEMENT_TOLERANCE_DEG
    )
    assert wide.matches > reports[2].matches
    again = match_keyframes(databases[2], scene.camera, poses, raycaster)
    assert again.matches == reports[0].matches
    rematched = read_correspondences(databases[2].path, names)
    for field in ("observer", "source", "uv_observer", "uv_source", "match"):
        np.testing.assert_array_equal(getattr(rematched, field), getattr(matches[0], field))
