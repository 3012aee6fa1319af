"""Pose refinement anchored on the LiDAR mesh, on synthetic matches with a known truth."""

from pathlib import Path

import numpy as np
import pytest
import trimesh
from scipy.spatial.transform import Rotation

from rig import CameraModel, invert, make_transform, transform_points
from rig.mesh_rays import mesh_points, mesh_raycaster
from slam_bridge.colmap_matches import Correspondences
from slam_bridge.pose_refinement import refine_keyframe_poses, restore_slow_errors

CAMERA = CameraModel("pinhole", 320, 240, [[250.0, 0, 159.5], [0, 250.0, 119.5], [0, 0, 1]], [])


def room() -> trimesh.Trimesh:
    """A 6 × 4 × 2.5 m room (normals facing in) with a box in a corner, floor at z = 0."""
    walls = trimesh.creation.box(extents=[6.0, 4.0, 2.5])
    walls.invert()
    box = trimesh.creation.box(
        extents=[0.8, 0.6, 0.7], transform=make_transform(np.eye(3), [2.2, -1.4, -0.9])
    )
    mesh = trimesh.util.concatenate([walls, box])
    mesh.apply_translation([0.0, 0.0, 1.25])
    return mesh


def true_poses(count: int = 24) -> tuple[np.ndarray, np.ndarray]:
    """Stamps (0.5 s apart) and ``T_world_cam`` of a wheeled robot's camera: 0.5 m high, crossing
    the room on a gentle arc, turning 120° in 12 s, looking slightly down (OpenCV axes)."""
    s = np.linspace(0, 1, count)
    positions = np.c_[-2.0 + 3.5 * s, -0.6 + 0.9 * np.sin(np.pi * s), np.full(count, 0.5)]
    yaw = np.radians(-30 + 120 * s)
    forward = np.c_[np.cos(yaw), np.sin(yaw), np.full(count, -0.25)]
    forward /= np.linalg.norm(forward, axis=1, keepdims=True)
    right = np.cross(forward, [0.0, 0.0, 1.0])
    right /= np.linalg.norm(right, axis=1, keepdims=True)
    down = np.cross(forward, right)
    rotations = np.stack([right, down, forward], axis=2)
    return np.arange(count, dtype=np.int64) * 500_000_000, make_transform(rotations, positions)


def synthetic_matches(mesh: trimesh.Trimesh, poses: np.ndarray, pixel_noise: float = 0.3) -> Correspondences:
    """Matches between every two keyframes (as exhaustive matching finds them): surface points
    seen by both, projected with noise."""
    rng = np.random.default_rng(0)
    raycaster = mesh_raycaster(mesh)
    points, _ = trimesh.sample.sample_surface(mesh, 20_000, seed=0)
    seen = []
    for T in poses:
        uv = CAMERA.project(transform_points(invert(T), points))
        inside = np.isfinite(uv).all(axis=1) & CAMERA.in_image(np.nan_to_num(uv, nan=-1.0), margin=2)
        hit = mesh_points(raycaster, CAMERA, T, np.where(inside[:, None], uv, 0.0))
        visible = inside & (np.linalg.norm(hit - points, axis=1) < 1e-3)  # not hidden by the box
        seen.append((visible, uv + rng.normal(0, pixel_noise, uv.shape)))
    parts: dict[str, list[np.ndarray]] = {k: [] for k in ("observer", "source", "uv_o", "uv_s", "match")}
    count = 0
    for i in range(len(poses)):
        for j in range(i + 1, len(poses)):
            both = np.flatnonzero(seen[i][0] & seen[j][0])
            for a, b in ((i, j), (j, i)):
                parts["observer"].append(np.full(len(both), a))
                parts["source"].append(np.full(len(both), b))
                parts["uv_o"].append(seen[a][1][both])
                parts["uv_s"].append(seen[b][1][both])
                parts["match"].append(count + np.arange(len(both)))
            count += len(both)
    return Correspondences(
        *(np.concatenate(parts[k]) for k in ("observer", "source", "uv_o", "uv_s", "match"))
    )


def perturbed(poses: np.ndarray, sigma_m: float, sigma_deg: float, seed: int) -> np.ndarray:
    rng = np.random.default_rng(seed)
    turn = Rotation.from_rotvec(rng.normal(0, np.radians(sigma_deg), (len(poses), 3))).as_matrix()
    return poses @ make_transform(turn, rng.normal(0, sigma_m, (len(poses), 3)))


def errors(poses: np.ndarray, truth: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Position (m) and rotation (deg) error of each pose."""
    turn = Rotation.from_matrix(truth[:, :3, :3].transpose(0, 2, 1) @ poses[:, :3, :3]).magnitude()
    return np.linalg.norm(poses[:, :3, 3] - truth[:, :3, 3], axis=1), np.degrees(turn)


@pytest.fixture(scope="module")
def scene() -> tuple[trimesh.Trimesh, np.ndarray, np.ndarray, Correspondences]:
    mesh = room()
    t_ns, truth = true_poses()
    return mesh, t_ns, truth, synthetic_matches(mesh, truth)


def refine(scene, start: np.ndarray, correspondences: Correspondences | None = None):
    mesh, t_ns, _, matches = scene
    names = [f"kf_{k:04d}" for k in range(len(start))]
    return refine_keyframe_poses(names, t_ns, start, CAMERA, correspondences or matches, mesh_raycaster(mesh))


@pytest.mark.parametrize("seed", [1, 2])
def test_refinement_reduces_pose_noise(scene, seed: int) -> None:
    truth = scene[2]
    noisy = perturbed(truth, 0.03 / np.sqrt(3), 0.5 / np.sqrt(3), seed)  # 3 cm / 0.5° RMS per pose
    refined, report = refine(scene, noisy)
    before_m, before_deg = errors(noisy, truth)
    after_m, after_deg = errors(refined, truth)
    assert report.refused is None and report.refined >= 20, report
    assert report.heldout_px_after < 0.5 * report.heldout_px_before
    assert np.median(after_m) < 0.5 * np.median(before_m), (np.median(before_m), np.median(after_m))
    assert np.median(after_deg) < 0.5 * np.median(before_deg), (np.median(before_deg), np.median(after_deg))


def test_true_poses_are_kept(scene) -> None:
    truth = scene[2]
    refined, report = refine(scene, truth)
    moved_m, turned_deg = errors(refined, truth)
    # Nothing to gain on exact poses: the held-out error cannot drop, so the guard keeps them.
    assert report.refused is not None and report.refined == 0
    np.testing.assert_array_equal(refined, truth)
    assert moved_m.max() == 0 and turned_deg.max() == 0


def test_wrong_matches_are_refused(scene) -> None:
    truth = scene[2]
    matches = scene[3]
    shuffled = np.random.default_rng(0).permutation(len(matches))
    garbage = Correspondences(
        matches.observer, matches.source, matches.uv_observer[shuffled], matches.uv_source, matches.match
    )
    noisy = perturbed(truth, 0.02, 0.3, 3)
    refined, report = refine(scene, noisy, garbage)
    assert report.refused is not None
    np.testing.assert_array_equal(refined, noisy)


def test_slow_errors_go_back_to_the_lidar_and_fast_ones_stay_refined() -> None:
    t_ns, truth = true_poses(40)
    drifted = truth.copy()  # the same error everywhere (the slowest there is)
    drifted[:, :3, :3] = Rotation.from_euler("z", 0.5, degrees=True).as_matrix() @ truth[:, :3, :3]
    drifted[:, :3, 3] += [0.03, -0.02, 0.01]
    restored = restore_slow_errors(drifted, truth, t_ns, sigma_s=2.0)
    np.testing.assert_allclose(restored, truth, atol=1e-9)

    jitter = truth.copy()
    jitter[:, 2, 3] += np.where(np.arange(40) % 2, 0.02, -0.02)  # alternating: fast
    kept = restore_slow_errors(truth, jitter, t_ns, sigma_s=2.0)
    assert np.abs(kept[:, :3, 3] - truth[:, :3, 3]).max() < 0.002  # the LiDAR's jitter is not let back in


def test_lts_prepare_refine_poses_on_the_true_trajectory(
    quick_room: Path, gt_slam_dir: Path, tmp_path: Path
) -> None:
    import json
    import subprocess
    import sys

    from slam_bridge.scene import load_scene

    lts = Path(sys.executable).parent / "lts"
    calib = quick_room / "ground_truth" / "calib.yaml"
    args = [lts, "prepare", quick_room / "session.mcap", "--calib", calib, "--slam", gt_slam_dir]
    plain = subprocess.run([*args, "--out", tmp_path / "plain"], capture_output=True, text=True, timeout=300)
    refined = subprocess.run(
        [*args, "--out", tmp_path / "refined", "--refine-poses"], capture_output=True, text=True, timeout=300
    )
    assert plain.returncode == 0 and refined.returncode == 0, refined.stderr[-2000:]
    assert "pose refinement" in refined.stderr
    report = json.loads((tmp_path / "refined" / "scene.json").read_text())["source"]["pose_refinement"]
    before = np.array([k.T_world_cam for k in load_scene(tmp_path / "plain").keyframes])
    after = np.array([k.T_world_cam for k in load_scene(tmp_path / "refined").keyframes])
    moved_m, turned_deg = errors(after, before)
    assert moved_m.max() == pytest.approx(report["max_move_m"])
    assert turned_deg.max() == pytest.approx(report["max_turn_deg"], abs=1e-6)
    assert moved_m.max() < 0.01 and turned_deg.max() < 0.2  # true poses: not made worse
