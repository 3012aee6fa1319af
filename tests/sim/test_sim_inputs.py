"""User meshes and trajectories, bad input, reproducibility, presets and the IMU."""

from __future__ import annotations

import filecmp
import subprocess
import sys
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
import trimesh
import yaml
from scipy.spatial.transform import Rotation

from rig.errors import InputError
from rig.session import DEFAULT_TOPICS, SessionReader
from rig.sim.config import SimConfig
from rig.sim.simulate import prepare, simulate
from rig.trajectory import Trajectory
from rig.trajectory_io import read_tum, write_matrix_lines

BIN = Path(sys.executable).parent


def _box_room(path: Path) -> Path:
    """A 4 × 4 × 3 m inward-facing box with vertex colours, centred at the origin."""
    box = trimesh.creation.box(extents=(4.0, 4.0, 3.0))
    room = trimesh.Trimesh(box.vertices, box.faces[:, ::-1])
    room.visual.vertex_colors = np.random.default_rng(0).integers(
        0, 255, (len(room.vertices), 4), dtype=np.uint8
    )
    room.export(path)
    return path


def _poses(n: int) -> np.ndarray:
    """``n`` camera-to-world poses turning slowly in place, camera looking horizontally."""
    yaw = np.linspace(0.0, 0.5, n)
    R_body_cam = np.array([[0.0, 0.0, 1.0], [-1.0, 0.0, 0.0], [0.0, -1.0, 0.0]])
    T = np.tile(np.eye(4), (n, 1, 1))
    T[:, :3, :3] = Rotation.from_euler("z", yaw[:, None]).as_matrix() @ R_body_cam
    T[:, :3, 3] = np.column_stack([np.linspace(0, 0.3, n), np.zeros(n), np.full(n, 0.5)])
    return T


def test_user_mesh_and_timeless_trajectory_at_rate(tmp_path: Path) -> None:
    mesh = _box_room(tmp_path / "room.ply")
    traj_path = tmp_path / "traj.txt"
    poses = _poses(14)  # 13 / 30 s is not a whole number of nanoseconds
    write_matrix_lines(Trajectory.from_poses(np.arange(14, dtype=np.int64), poses), traj_path)
    config = SimConfig(
        mesh=str(mesh), trajectory=str(traj_path), trajectory_rate_hz=30.0, width=64, height=48
    )
    summary = simulate(config, tmp_path / "out")
    assert summary["frames"] == 14 and summary["scans"] == 4  # 0.43 s of poses
    gt = read_tum(tmp_path / "out" / "ground_truth" / "trajectory.tum")
    assert np.allclose(gt.poses, poses, atol=1e-9)  # frames at the trajectory's own poses
    frames = list(SessionReader(tmp_path / "out" / "session.mcap").frames(DEFAULT_TOPICS["image"]))
    assert len(frames) == 14 and frames[0].image.std() > 10  # the vertex colours show


def test_mesh_without_faces_is_named(tmp_path: Path) -> None:
    points = tmp_path / "points.ply"
    trimesh.PointCloud(np.random.default_rng(0).random((20, 3))).export(points)
    traj = tmp_path / "traj.txt"
    write_matrix_lines(Trajectory.from_poses(np.arange(3, dtype=np.int64), _poses(3)), traj)
    with pytest.raises(InputError, match=r"points\.ply: faces: mesh has no faces"):
        prepare(SimConfig(mesh=str(points), trajectory=str(traj)))


def test_trajectory_with_one_pose_is_named(tmp_path: Path) -> None:
    mesh = _box_room(tmp_path / "room.ply")
    traj = tmp_path / "one.tum"
    traj.write_text("1.0 0 0 0.5 0 0 0 1\n")
    with pytest.raises(InputError, match=r"one\.tum: trajectory: .*at least 2 poses.*, got 1"):
        prepare(SimConfig(mesh=str(mesh), trajectory=str(traj)))


def test_unknown_preset_gives_one_line_error(tmp_path: Path) -> None:
    result = subprocess.run(
        [BIN / "lts", "sim", tmp_path / "out", "--preset", "garage"],
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert result.returncode == 2
    lines = [line for line in result.stderr.splitlines() if line.strip()]
    assert len(lines) == 1 and "unknown preset 'garage'" in lines[0] and "room, corridor, stairs" in lines[0]


@pytest.mark.parametrize(
    ("option", "says"),
    [
        (["--image-noise", "-1"], "image_noise: expected a standard deviation >= 0"),
        (["--exposure-jitter", "-0.1"], "exposure_jitter: expected a standard deviation >= 0"),
        (["--lidar-points", "0"], "Invalid value for '--lidar-points'"),
    ],
)
def test_a_negative_noise_or_no_lidar_points_is_one_line_error(
    tmp_path: Path, option: list[str], says: str
) -> None:
    """They were taken as no noise (a negative standard deviation) or overridden by --quick."""
    result = subprocess.run(
        [BIN / "lts", "sim", tmp_path / "out", "--quick", *option],
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert result.returncode == 2 and "Traceback" not in result.stderr, result.stderr
    assert says in result.stderr.strip().splitlines()[-1]
    assert not (tmp_path / "out").exists()


def test_quick_keeps_the_sizes_given_with_it(tmp_path: Path) -> None:
    out = tmp_path / "out"
    result = subprocess.run(
        [BIN / "lts", "sim", out, "--quick", "--width", "200", "--duration", "1"],
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert result.returncode == 0, result.stderr
    calibration = yaml.safe_load((out / "ground_truth" / "calib.yaml").read_text())
    assert (calibration["camera"]["width"], calibration["camera"]["height"]) == (200, 120)
    assert SessionReader(out / "session.mcap").topics()[DEFAULT_TOPICS["image"]].count == 31  # 1 s at 30 Hz


def test_same_seed_gives_identical_files_scene_yaml_regenerates_other_seed_differs(tmp_path: Path) -> None:
    config = replace(SimConfig(seed=3).quick(), duration_s=1.0)
    for name, cfg in (("a", config), ("b", config), ("c", replace(config, seed=4))):
        simulate(cfg, tmp_path / name)
    assert SimConfig.from_scene_yaml(tmp_path / "a" / "ground_truth" / "scene.yaml") == config
    files = [
        "session.mcap",
        *(f"ground_truth/{f}" for f in ("mesh.ply", "trajectory.tum", "calib.yaml", "scene.yaml")),
    ]
    assert all(filecmp.cmp(tmp_path / "a" / f, tmp_path / "b" / f, shallow=False) for f in files)
    assert not filecmp.cmp(tmp_path / "a" / "session.mcap", tmp_path / "c" / "session.mcap", shallow=False)


@pytest.mark.parametrize(
    ("preset", "lidar", "carrier"), [("corridor", "spinning", "wheeled"), ("stairs", "rosette", "handheld")]
)
def test_presets_lidars_and_carriers_run(tmp_path: Path, preset: str, lidar: str, carrier: str) -> None:
    config = SimConfig(preset=preset, lidar=lidar, carrier=carrier, duration_s=0.5, width=64, height=48)
    summary = simulate(config, tmp_path)
    expected = 32 * 1024 if lidar == "spinning" else config.lidar_points
    assert 0.9 * expected < summary["points_per_scan_mean"] <= expected
    heights = read_tum(tmp_path / "ground_truth" / "trajectory.tum").translations[:, 2]
    low, high = (0.35, 0.55) if carrier == "wheeled" else (1.2, 1.6)
    assert low <= heights.min() and heights.max() <= high


def test_imu_measures_the_ground_truth_motion(quick_run: Path) -> None:
    gt = quick_run / "ground_truth"
    scene = yaml.safe_load((gt / "scene.yaml").read_text())
    samples = list(SessionReader(quick_run / "session.mcap").imu(DEFAULT_TOPICS["imu"]))
    gyro = np.array([s.angular_velocity for s in samples]) - scene["rig"]["imu_gyro_bias"]
    accel = np.array([s.linear_acceleration for s in samples]) - scene["rig"]["imu_accel_bias"]
    traj = read_tum(gt / "trajectory_lidar.tum")  # the IMU frame is the LiDAR frame
    assert np.array_equal(traj.t_ns, [s.t_host for s in samples])
    dt = np.diff(traj.t_ns) * 1e-9
    relative = np.einsum("nji,njk->nik", traj.rotations[:-1], traj.rotations[1:])
    omega = Rotation.from_matrix(relative).as_rotvec() / dt[:, None]  # body rates between samples
    midpoint_gyro = (gyro[:-1] + gyro[1:]) / 2
    assert np.abs(midpoint_gyro - omega).mean() < 0.01  # noise 0.003 rad/s per sample
    assert np.linalg.norm(accel, axis=1).mean() == pytest.approx(9.81, abs=0.1)


def test_textured_mesh_is_sampled_through_its_uv_map(tmp_path: Path) -> None:
    from PIL import Image

    from rig.sim.world import mesh_world

    # A quad on the plane z = 0 whose texture is red on the left half (u < 0.5), blue on the right.
    texture = np.zeros((8, 8, 3), dtype=np.uint8)
    texture[:, :4, 0] = 255
    texture[:, 4:, 2] = 255
    quad = trimesh.Trimesh(
        vertices=[[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]],
        faces=[[0, 1, 2], [0, 2, 3]],
        visual=trimesh.visual.TextureVisuals(
            uv=[[0, 0], [1, 0], [1, 1], [0, 1]], image=Image.fromarray(texture)
        ),
        process=False,
    )
    quad.export(tmp_path / "quad.obj")
    world = mesh_world(tmp_path / "quad.obj")
    origins = np.array([[0.25, 0.5, 1.0], [0.75, 0.5, 1.0]])
    hits = world.raycaster.cast(origins, np.array([[0.0, 0.0, -1.0]] * 2))
    colour = world.appearance.colour(hits, np.zeros(2))
    assert np.allclose(colour, [[1, 0, 0], [0, 0, 1]], atol=0.01)  # the mesh's own colours, unshaded


def test_the_quick_run_moves_from_its_first_frame_to_its_last():
    quick = prepare(SimConfig(preset="room").quick()).motion
    full = prepare(SimConfig(preset="room", duration_s=3.0)).motion
    t = np.array([0.0, 0.05, 2.95, 3.0])
    for motion, moving in ((quick, True), (full, False)):
        p = motion.positions(t)
        first, last = np.linalg.norm(p[1] - p[0]) / 0.05, np.linalg.norm(p[3] - p[2]) / 0.05
        if moving:  # at about the room's 0.45 m/s at both ends (a spline's speed varies a little)
            assert 0.3 < first < 0.6 and 0.3 < last < 0.6
        else:  # from rest, to rest
            assert first < 0.05 and last < 0.05
    assert np.linalg.norm(np.diff(quick.positions(np.linspace(0, 3, 300)), axis=0), axis=1).sum() > 1.2
