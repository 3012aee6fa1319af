"""The simulated streams agree with an independent computation from the ground-truth files."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import open3d as o3d
import pytest
import trimesh
import yaml
from scipy.spatial.transform import Rotation

from rig.calibration import load_calibration
from rig.session import DEFAULT_TOPICS, SessionReader
from rig.sim.camera_sim import CameraSimulator
from rig.sim.config import SimConfig
from rig.sim.simulate import prepare
from rig.trajectory_io import read_tum
from rig.transforms import invert, transform_points


def _raycasting_scene(mesh_path: Path) -> o3d.t.geometry.RaycastingScene:
    mesh = trimesh.load(mesh_path, process=False)
    scene = o3d.t.geometry.RaycastingScene()
    scene.add_triangles(
        o3d.core.Tensor(np.asarray(mesh.vertices, dtype=np.float32)),
        o3d.core.Tensor(np.asarray(mesh.faces, dtype=np.uint32)),
    )
    return scene


def _cast(scene: o3d.t.geometry.RaycastingScene, origins: np.ndarray, dirs: np.ndarray) -> np.ndarray:
    rays = np.concatenate([np.broadcast_to(origins, dirs.shape), dirs], axis=1).astype(np.float32)
    return scene.cast_rays(o3d.core.Tensor(rays))["t_hit"].numpy().astype(np.float64)


def test_lidar_ranges_match_ray_cast_distance_within_3_sigma(
    quick_run: Path, quick_config: SimConfig
) -> None:
    gt = quick_run / "ground_truth"
    scene = _raycasting_scene(gt / "mesh.ply")
    lidar_traj = read_tum(gt / "trajectory_lidar.tum")
    sigma = quick_config.range_noise_m
    errors, skew = [], []
    scans = list(SessionReader(quick_run / "session.mcap").scans(DEFAULT_TOPICS["points"]))
    assert len(scans) == 30
    for scan in scans[5::6]:
        assert scan.point_time_s.min() >= 0 and scan.point_time_s.max() < 0.1
        points = np.asarray(scan.points, dtype=np.float64)
        ranges = np.linalg.norm(points, axis=1)
        poses = lidar_traj.interpolate(scan.point_times_ns(host=True))
        dirs_world = np.einsum("nij,nj->ni", poses[:, :3, :3], points / ranges[:, None])
        errors.append(ranges - _cast(scene, poses[:, :3, 3], dirs_world))
        # The same points placed with the sweep-start pose instead: the motion skew deskewing removes.
        start = poses[np.argmin(scan.point_time_s)]
        skew.append(
            np.linalg.norm(
                transform_points(start, points) - (poses[:, :3, 3] + dirs_world * ranges[:, None]), axis=1
            )
        )
    err = np.concatenate(errors)
    assert np.mean(np.abs(err) <= 3 * sigma) > 0.99
    assert np.std(err[np.abs(err) <= 3 * sigma]) == pytest.approx(sigma, rel=0.15)
    assert np.percentile(np.concatenate(skew), 90) > sigma  # moving during the sweep matters


@pytest.mark.parametrize("model", ["pinhole", "fisheye"])
def test_mesh_vertex_projects_onto_pixel_with_its_depth(
    quick_run: Path, quick_config: SimConfig, model: str
) -> None:
    gt = quick_run / "ground_truth"
    config = SimConfig(**{**quick_config.to_dict(), "camera_model": model})
    run = prepare(config)
    camera = config.camera()
    k = 45
    T_world_cam = read_tum(gt / "trajectory.tum").poses[k]
    assert np.allclose(T_world_cam, run.motion.poses(run.frame_times[k : k + 1])[0], atol=1e-9)
    _, depth = CameraSimulator(camera).render(run.world, T_world_cam)

    vertices = np.asarray(trimesh.load(gt / "mesh.ply", process=False).vertices)
    cam = transform_points(invert(T_world_cam), vertices)
    pixels = camera.project(cam)
    ok = camera.in_image(pixels, margin=1.0) & (cam[:, 2] > 0.3)
    # Visible: nothing lies between the camera and the vertex (independent ray cast).
    to_vertex = vertices[ok] - T_world_cam[:3, 3]
    distance = np.linalg.norm(to_vertex, axis=1)
    hit = _cast(_raycasting_scene(gt / "mesh.ply"), T_world_cam[:3, 3], to_vertex / distance[:, None])
    visible = hit > distance - 0.01
    assert visible.sum() > 100
    px = pixels[ok][visible]
    z = cam[ok][visible, 2]
    # The depth rendered at the pixels around the vertex, interpolated to where it projects.
    i0 = np.floor(px).astype(int)
    fx, fy = (px - i0).T
    d00, d01 = depth[i0[:, 1], i0[:, 0]], depth[i0[:, 1], i0[:, 0] + 1]
    d10, d11 = depth[i0[:, 1] + 1, i0[:, 0]], depth[i0[:, 1] + 1, i0[:, 0] + 1]
    rendered = (1 - fy) * ((1 - fx) * d00 + fx * d01) + fy * ((1 - fx) * d10 + fx * d11)
    corners = np.stack([d00, d01, d10, d11])
    continuous = np.ptp(corners, axis=0) < 0.2 * z  # not across a silhouette
    assert continuous.mean() > 0.8
    relative = (np.abs(rendered - z) / z)[continuous]
    # Exact up to the interpolation across creases (a 0.5 px shift of the principal point gives
    # a median of ~6e-4 and only ~80 % within 1 % for the pinhole camera).
    assert np.median(relative) < 2e-4
    assert np.mean(relative < 0.01) > 0.9


def test_time_offset_drift_and_extrinsic_match_calibration(quick_run: Path) -> None:
    gt = quick_run / "ground_truth"
    calib = load_calibration(gt / "calib.yaml")
    clocks = yaml.safe_load((gt / "scene.yaml").read_text())["clocks"]
    reader = SessionReader(quick_run / "session.mcap")
    stamps = {}
    for name, topic in (("camera", DEFAULT_TOPICS["image"]), ("lidar", DEFAULT_TOPICS["points"])):
        pairs = np.array([(m.t_device, m.t_host) for m in reader.messages([topic])], dtype=np.int64)
        # Map the device clock to the host clock by a linear fit; its slope is the drift.
        dev, host = (pairs[:, 0] - pairs[0, 0]) * 1e-9, (pairs[:, 1] - pairs[0, 1]) * 1e-9
        slope = np.polyfit(dev, host, 1)[0]
        assert (1 / slope - 1) * 1e6 == pytest.approx(clocks[name]["drift_ppm"], abs=0.01)
        stamps[name] = pairs[:, 1]
    # Frames run at 30 Hz and sweeps at 10 Hz from the same instant: frame 3j is taken with sweep j.
    n = len(stamps["lidar"])
    offsets = (stamps["camera"][: 3 * n : 3] - stamps["lidar"]) * 1e-9
    assert np.allclose(offsets, calib.time_offset_s, atol=1e-9)

    # Ground truth: the camera pose at camera time t is the LiDAR pose at LiDAR time t - offset.
    cam_traj, lidar_traj = read_tum(gt / "trajectory.tum"), read_tum(gt / "trajectory_lidar.tum")
    t_lidar = cam_traj.t_ns - round(calib.time_offset_s * 1e9)
    inside = lidar_traj.covers(t_lidar)
    predicted = lidar_traj.interpolate(t_lidar[inside]) @ invert(calib.T_cam_lidar)
    assert np.abs(predicted[:, :3, 3] - cam_traj.poses[inside, :3, 3]).max() < 1e-4
    assert np.abs(predicted[:, :3, :3] - cam_traj.poses[inside, :3, :3]).max() < 1e-4


def test_trajectory_is_smooth_with_bounded_jerk(quick_run: Path) -> None:
    traj = read_tum(quick_run / "ground_truth" / "trajectory.tum")
    dt = np.diff(traj.t_ns) * 1e-9
    assert np.allclose(dt, dt[0], rtol=1e-6)
    p = traj.translations
    speed = np.linalg.norm(np.diff(p, axis=0), axis=1) / dt[0]
    jerk = np.linalg.norm(np.diff(p, 3, axis=0), axis=1) / dt[0] ** 3
    assert speed.max() < 1.0  # a slow indoor robot
    assert jerk.max() < 5.0  # m/s³
    relative = np.einsum("nji,njk->nik", traj.rotations[:-1], traj.rotations[1:])
    angular_speed = np.linalg.norm(Rotation.from_matrix(relative).as_rotvec(), axis=1) / dt[0]
    assert angular_speed.max() < 1.5  # rad/s: slow yaw
    forward = traj.rotations[:, :, 2]  # camera z axis in the world
    assert np.abs(forward[:, 2]).max() < np.sin(np.deg2rad(15))  # looks ahead, roughly level
