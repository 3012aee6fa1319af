"""Ground truth of a simulated run: coloured mesh, trajectories, calibration and scene description.

Every trajectory file is stamped like the messages it describes (host clock, ns in the file as
seconds): ``trajectory.tum`` holds the camera poses at the camera frames' ``t_host``;
``trajectory_lidar.tum`` the LiDAR (= IMU) poses at the IMU samples' ``t_host``, which is the
timeline of the scans too (a point's time is its scan's ``t_host`` + its per-point offset).
"""

from __future__ import annotations

from dataclasses import asdict
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
import yaml

from rig.calibration import Calibration, save_calibration
from rig.sim.clocks import HOST_START_NS
from rig.sim.imu_sim import ImuReadings
from rig.trajectory import Trajectory
from rig.trajectory_io import write_tum

if TYPE_CHECKING:
    from rig.sim.simulate import SimRun


def write_ground_truth(run: SimRun, gt_dir: Path, imu: ImuReadings) -> None:
    """Write ``mesh.ply`` (the static scene), ``trajectory.tum``, ``trajectory_lidar.tum``,
    ``calib.yaml``, ``scene.yaml`` and, for a world with movers, ``movers/NAME.ply`` (each in its
    own frame) and ``movers/NAME.tum`` (its poses at the camera frames) into ``gt_dir``."""
    gt_dir.mkdir(parents=True, exist_ok=True)
    run.world.appearance.coloured_mesh(run.world.mesh).export(gt_dir / "mesh.ply")
    frame_t, imu_t = run.frame_times, run.imu_times
    write_tum(run.motion.trajectory(frame_t, run.camera_clock.host_ns(frame_t)), gt_dir / "trajectory.tum")
    write_tum(
        run.motion.trajectory(imu_t, run.lidar_clock.host_ns(imu_t), run.T_cam_lidar),
        gt_dir / "trajectory_lidar.tum",
    )
    _write_movers(run, gt_dir / "movers")
    camera = run.config.camera()
    quality = {"source": "ground truth of a simulated run (lts sim)"}
    save_calibration(
        Calibration(camera, run.T_cam_lidar, run.config.time_offset_s, quality), gt_dir / "calib.yaml"
    )
    scene = {
        "config": run.config.to_dict(),
        "world": run.world.name,
        "duration_s": run.motion.duration_s,
        "counts": {"frames": len(frame_t), "scans": len(run.scan_times), "imu": len(imu_t)},
        "clocks": {
            "host_start_ns": HOST_START_NS,
            "camera": run.camera_clock.to_dict(),
            "lidar": run.lidar_clock.to_dict(),
            "imu": "shares the lidar clock",
            "model": "device = offset_s + (1 + drift_ppm 1e-6) t;  host = host_start + t + latency_s",
        },
        "rig": {
            "T_cam_lidar": run.T_cam_lidar.tolist(),
            "T_cam_imu": run.T_cam_lidar.tolist(),
            "lidar": asdict(run.lidar),
            "imu": asdict(run.imu),
            "imu_gyro_bias": imu.gyro_bias.tolist(),
            "imu_accel_bias": imu.accel_bias.tolist(),
        },
        "camera": camera.to_dict(),
        "sky": run.world.sky,
        "movers": [
            {"name": m.name, "start_xy": list(m.start_xy), "velocity_xy": list(m.velocity_xy)}
            for m in run.world.movers
        ],
        "frames": {
            "world": "z up, metres",
            "camera": "OpenCV (x right, y down, z forward)",
            "lidar": "x forward, y left, z up; the IMU frame is the LiDAR frame",
        },
    }
    text = yaml.safe_dump(_plain(scene), sort_keys=False, default_flow_style=None)
    (gt_dir / "scene.yaml").write_text(text)


def _write_movers(run: SimRun, movers_dir: Path) -> None:
    if not run.world.movers:
        return
    movers_dir.mkdir(exist_ok=True)
    frame_t = run.frame_times
    for mover in run.world.movers:
        mover.mesh.export(movers_dir / f"{mover.name}.ply")
        write_tum(
            Trajectory.from_poses(run.camera_clock.host_ns(frame_t), mover.poses(frame_t)),
            movers_dir / f"{mover.name}.tum",
        )


def _plain(value: object) -> object:
    """Nested numpy values as plain Python, for YAML."""
    if isinstance(value, dict):
        return {k: _plain(v) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [_plain(v) for v in value]
    if isinstance(value, np.generic):
        return value.item()
    return value
