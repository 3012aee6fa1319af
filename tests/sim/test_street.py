"""The ``street`` preset: moving vehicles cast at each ray's time, sky, a KITTI-like LiDAR field,
and a ground truth of the static street and of every vehicle's motion."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import trimesh
import yaml

from rig.errors import InputError
from rig.sim.camera_sim import CameraSimulator
from rig.sim.config import SimConfig
from rig.sim.lidar_sim import simulate_scan
from rig.sim.movers import Mover, MovingRaycaster, inside_movers, mover_of_face
from rig.sim.simulate import prepare
from rig.sim.world import SKY_HORIZON, SKY_ZENITH
from rig.trajectory_io import read_tum

BIN = Path(sys.executable).parent


def _cube_mover(velocity: tuple[float, float]) -> Mover:
    cube = trimesh.creation.box(extents=(2.0, 2.0, 2.0))
    cube.apply_translation((0.0, 0.0, 1.0))
    return Mover("cube", cube, np.zeros(len(cube.faces), dtype=np.int64), (10.0, 0.0), velocity)


def test_a_mover_drives_at_constant_velocity_facing_where_it_goes() -> None:
    mover = _cube_mover((0.0, 2.0))
    T = mover.poses(np.array([0.0, 1.5]))
    np.testing.assert_allclose(T[:, :3, 3], [[10.0, 0.0, 0.0], [10.0, 3.0, 0.0]])
    np.testing.assert_allclose(T[0, :3, 0], [0.0, 1.0, 0.0], atol=1e-12)  # x forward = along +y
    points = np.array([[10.0, 3.0, 1.0], [10.0, 6.0, 1.0], [10.0, 3.0, 2.5]])
    assert inside_movers(points, (mover,), np.array([1.5])).tolist() == [True, False, False]
    assert inside_movers(points, (mover,), np.linspace(0.0, 3.0, 31)).tolist() == [True, True, False]


def test_rays_hit_a_mover_where_it_is_at_the_ray_time() -> None:
    ground = trimesh.creation.box(extents=(100.0, 100.0, 0.2))
    ground.apply_translation((0.0, 0.0, -0.1))
    mover = _cube_mover((5.0, 0.0))
    caster = MovingRaycaster(ground, (mover,))
    origins = np.array([[0.0, 0.0, 1.0], [0.0, 0.0, 1.0]])
    directions = np.array([[1.0, 0.0, 0.0], [1.0, 0.0, 0.0]])
    hits = caster.cast(origins, directions, np.array([0.0, 2.0]))
    # At 0 s the cube's back face is at x = 9; at 2 s it has moved 10 m on.
    np.testing.assert_allclose(hits.distance, [9.0, 19.0], atol=0.02)
    assert mover_of_face(hits.face, len(ground.faces), (mover,)).tolist() == [0, 0]
    down = caster.cast(np.array([0.0, 0.0, 1.0]), np.array([[0.0, 0.0, -1.0]]), 0.0)
    assert mover_of_face(down.face, len(ground.faces), (mover,)).tolist() == [-1]


@pytest.fixture(scope="module")
def street_run():
    return prepare(SimConfig(preset="street").quick())  # 3 s


def test_street_defaults_are_a_car_with_a_kitti_like_lidar_and_a_wide_camera() -> None:
    config = SimConfig(preset="street")
    assert (config.carrier, config.lidar, config.width, config.height, config.max_range_m) == (
        "car", "velodyne64", 640, 240, 80.0,
    )  # fmt: skip
    assert SimConfig(preset="street", lidar="velodyne32", width=320).width == 320
    assert SimConfig(preset="room").lidar == "mid360"
    assert prepare(SimConfig(preset="street", traffic=False).quick()).world.movers == ()


def test_a_creeping_drive_keeps_the_cars_of_its_lane_at_its_speed() -> None:
    """--speed: the ego car and the cars in its lane at 0.85 m/s; the others as at the preset's 3."""
    creeping = prepare(SimConfig(preset="street", speed_mps=0.85).quick())
    cruising = prepare(SimConfig(preset="street").quick())
    assert SimConfig(preset="street").speed_mps == 3.0 and SimConfig(preset="office").speed_mps == 0.5
    assert SimConfig(mesh="m.ply", trajectory="t.tum").speed_mps is None
    t = creeping.frame_times
    path = creeping.motion.poses(t)[:, :3, 3]
    assert np.linalg.norm(path[-1] - path[0]) / (t[-1] - t[0]) == pytest.approx(0.85, rel=0.05)
    for slow, fast in zip(creeping.world.movers, cruising.world.movers, strict=True):
        velocity = np.asarray(slow.velocity_xy) - np.asarray(fast.velocity_xy)
        in_lane = slow.name in ("car_ahead", "car_behind")
        np.testing.assert_allclose(velocity, (-2.15, 0.0) if in_lane else (0.0, 0.0), atol=1e-12)
    with pytest.raises(InputError, match="speed_mps"):
        SimConfig(preset="street", speed_mps=0.0)


def test_the_camera_sees_sky_and_what_is_above_the_lidar_field(street_run) -> None:
    rgb, depth = CameraSimulator(street_run.config.camera()).render(
        street_run.world, street_run.motion.poses(np.array([2.0]))[0], 2.0
    )
    sky = np.isnan(depth)
    assert 0.05 < sky.mean() < 0.6 and sky[0].mean() > sky[-1].mean()  # sky above, road below
    low, high = np.minimum(SKY_HORIZON, SKY_ZENITH), np.maximum(SKY_HORIZON, SKY_ZENITH)
    assert np.all((rgb[sky] >= low - 1e-6) & (rgb[sky] <= high + 1e-6))
    scan = simulate_scan(
        street_run.world, street_run.motion, street_run.lidar, street_run.T_cam_lidar, 2.0,
        np.random.default_rng(0),
    )  # fmt: skip
    elevation = np.degrees(np.arcsin(scan.points[:, 2] / np.linalg.norm(scan.points, axis=1)))
    assert elevation.max() < 2.5 and elevation.min() > -25.5
    assert np.linalg.norm(scan.points, axis=1).max() > 40.0  # far returns along the street


def test_below_the_horizon_the_camera_sees_the_ground_not_the_sky(street_run) -> None:
    # Between the building blocks and behind them lies ground; only beyond the street's far end
    # (150 m ahead: 0.7° below the horizon) does the sky reach below it.
    camera = CameraSimulator(street_run.config.camera())
    for t in np.arange(0.0, 3.0, 0.25):
        T_world_cam = street_run.motion.poses(np.array([t]))[0]
        _, depth = camera.render(street_run.world, T_world_cam, t)
        down = (camera.directions @ T_world_cam[:3, :3].T)[:, 2].reshape(depth.shape)
        assert not np.isnan(depth[down < -np.sin(np.radians(1.0))]).any(), t


def test_the_lidar_sees_the_traffic_at_its_own_time(street_run) -> None:
    world, run = street_run.world, street_run
    scan = simulate_scan(world, run.motion, run.lidar, run.T_cam_lidar, 2.0, np.random.default_rng(0))
    on_movers = inside_movers(scan.world_points, world.movers, 2.0 + np.arange(0.0, 0.1, 0.0025), 0.05)
    assert on_movers.sum() > 500  # the car ahead and behind, the lorry beside
    at_its_time = np.zeros(len(scan.world_points), dtype=bool)
    for t in np.unique(np.round(scan.time_s, 3)):
        rows = np.round(scan.time_s, 3) == t
        at_its_time[rows] = inside_movers(scan.world_points[rows], world.movers, np.array([2.0 + t]), 0.05)
    assert at_its_time.sum() >= 0.95 * on_movers.sum()


def test_lts_sim_street_writes_the_static_truth_and_each_vehicle_motion(tmp_path) -> None:
    out = tmp_path / "street"
    command = [BIN / "lts", "sim", out, "--preset", "street", "--quick"]
    result = subprocess.run(command, capture_output=True, text=True, timeout=600)
    assert result.returncode == 0, result.stderr
    gt = out / "ground_truth"
    scene = yaml.safe_load((gt / "scene.yaml").read_text())
    assert scene["sky"] is True and scene["config"]["lidar"] == "velodyne64"
    names = [m["name"] for m in scene["movers"]]
    assert {"car_ahead", "lorry_beside", "crossing"} <= set(names)
    frames = read_tum(gt / "trajectory.tum")
    run = prepare(SimConfig.from_scene_yaml(gt / "scene.yaml"))
    for mover in run.world.movers:
        track = read_tum(gt / "movers" / f"{mover.name}.tum")
        np.testing.assert_array_equal(track.t_ns, frames.t_ns)
        np.testing.assert_allclose(track.translations, mover.poses(run.frame_times)[:, :3, 3], atol=1e-9)
        assert len(trimesh.load(gt / "movers" / f"{mover.name}.ply").faces) == len(mover.mesh.faces)
    static = trimesh.load(gt / "mesh.ply")
    assert not inside_movers(static.vertices, run.world.movers, run.frame_times).any()  # no vehicle in it
