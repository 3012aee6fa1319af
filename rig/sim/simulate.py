"""The virtual rig's pipeline: world + motion → camera, LiDAR and IMU streams → session + truth."""

from __future__ import annotations

from collections.abc import Callable, Iterator
from concurrent.futures import Future, ThreadPoolExecutor
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from threadpoolctl import threadpool_limits

from rig.messages import Frame, ImuSample, Scan
from rig.session import SessionWriter
from rig.sim.camera_sim import CameraSimulator, to_bgr8
from rig.sim.clocks import SensorClock, rig_clocks
from rig.sim.config import SimConfig
from rig.sim.export import write_ground_truth
from rig.sim.imu_sim import ImuModel, simulate_imu
from rig.sim.lidar_sim import LidarModel, simulate_scan
from rig.sim.motion import Motion
from rig.sim.scenes import PRESETS, get_preset
from rig.sim.trajectories import path_motion
from rig.sim.world import World, mesh_world, preset_world
from rig.trajectory_io import read_trajectory

#: Default LiDAR mount for user meshes (the room preset's rig).
DEFAULT_T_CAM_LIDAR = PRESETS["room"].T_cam_lidar
#: Camera frames rendered this many ahead of the writer on a second thread, which bounds the
#: memory they hold.
FRAMES_AHEAD = 4


@dataclass
class SimRun:
    """A prepared run: the world, the camera motion, the rig and its clocks."""

    config: SimConfig
    world: World
    motion: Motion
    T_cam_lidar: np.ndarray
    camera_clock: SensorClock
    lidar_clock: SensorClock
    lidar: LidarModel
    imu: ImuModel

    # The 1e-6 below absorbs the nanosecond rounding of trajectory stamps (2000 poses at 30 Hz
    # end at 66.633333333 s, not 1999 / 30 s).

    @property
    def frame_times(self) -> np.ndarray:
        """True times ``(K,)`` (s) of the camera frames."""
        n = int(np.floor(self.motion.duration_s * self.config.fps + 1e-6)) + 1
        return np.minimum(np.arange(n) / self.config.fps, self.motion.duration_s)

    @property
    def scan_times(self) -> np.ndarray:
        """True start times ``(J,)`` (s) of the LiDAR sweeps that end within the motion."""
        n = int(np.floor(self.motion.duration_s * self.lidar.rate_hz + 1e-6))
        return np.arange(n) / self.lidar.rate_hz

    @property
    def imu_times(self) -> np.ndarray:
        """True times ``(I,)`` (s) of the IMU samples."""
        n = int(np.floor(self.motion.duration_s * self.imu.rate_hz + 1e-6)) + 1
        return np.minimum(np.arange(n) / self.imu.rate_hz, self.motion.duration_s)


def prepare(config: SimConfig) -> SimRun:
    """Build the world, motion, rig and clocks of ``config`` (raises InputError on bad input)."""
    seeds = np.random.SeedSequence(config.seed).spawn(2)
    rng_path, rng_clock = (np.random.default_rng(s) for s in seeds)
    if config.mesh is not None and config.trajectory is not None:
        trajectory = read_trajectory(config.trajectory, rate_hz=config.trajectory_rate_hz)
        motion = Motion.from_trajectory(trajectory, source=config.trajectory)  # before the slow mesh load
        world = mesh_world(config.mesh)
        T_cam_lidar = DEFAULT_T_CAM_LIDAR
    else:
        preset = get_preset(config.preset)
        world = preset_world(preset, config.seed, config.traffic, config.speed_mps)
        motion = path_motion(
            np.array(preset.waypoints),
            config.duration_s,
            rng=rng_path,
            carrier=config.carrier,
            speed_mps=config.speed_mps,
            closed=preset.closed,
            from_rest=config.from_rest,
        )  # type: ignore[arg-type]
        T_cam_lidar = preset.T_cam_lidar
    camera_clock, lidar_clock = rig_clocks(rng_clock, config.time_offset_s)
    lidar = LidarModel(
        config.lidar,  # type: ignore[arg-type]
        config.lidar_rate_hz,
        config.lidar_points,
        config.range_noise_m,
        config.dropout,
        max_range_m=config.max_range_m,
    )
    return SimRun(
        config, world, motion, T_cam_lidar, camera_clock, lidar_clock, lidar, ImuModel(config.imu_rate_hz)
    )


def simulate(
    config: SimConfig, out_dir: str | Path, progress: Callable[[int, int], None] | None = None
) -> dict[str, Any]:
    """Simulate ``config`` into ``out_dir``: ``session.mcap`` and ``ground_truth/`` (see :func:`record`)."""
    return record(prepare(config), out_dir, progress)


def record(
    run: SimRun, out_dir: str | Path, progress: Callable[[int, int], None] | None = None
) -> dict[str, Any]:
    """Record a prepared run into ``out_dir``: ``session.mcap`` and ``ground_truth/``.

    Messages are written in host-time order. ``progress(done, total)`` is called after each
    camera frame and LiDAR sweep. Returns a summary (counts, points per scan, paths).
    """
    config = run.config
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    rng_scan, rng_image, rng_imu = (
        np.random.default_rng(s) for s in np.random.SeedSequence([config.seed, 2]).spawn(3)
    )
    camera = config.camera()
    renderer = CameraSimulator(camera)
    frame_t, scan_t, imu_t = run.frame_times, run.scan_times, run.imu_times

    def render(i: int) -> np.ndarray:
        return renderer.render(run.world, run.motion.poses(frame_t[i : i + 1])[0], frame_t[i])[0]

    readings = simulate_imu(run.motion, run.imu, run.T_cam_lidar, imu_t, rng_imu)

    # One event list in host-time order: (host stamp, kind 0 frame / 1 scan / 2 imu, index).
    host = [
        run.camera_clock.host_ns(frame_t),
        run.lidar_clock.host_ns(scan_t),
        run.lidar_clock.host_ns(imu_t),
    ]
    device = [
        run.camera_clock.device_ns(frame_t),
        run.lidar_clock.device_ns(scan_t),
        run.lidar_clock.device_ns(imu_t),
    ]
    kinds = np.concatenate([np.full(len(h), k) for k, h in enumerate(host)])
    index = np.concatenate([np.arange(len(h)) for h in host])
    order = np.lexsort((index, kinds, np.concatenate(host)))
    total, done = len(frame_t) + len(scan_t), 0
    points_per_scan = []
    metadata = {"source": "lts sim", "preset": run.world.name, "seed": config.seed}
    with (
        threadpool_limits(1, user_api="blas"),
        SessionWriter(out / "session.mcap", metadata=metadata, image_format=config.image_format) as writer,
        rendered_ahead(render, len(frame_t)) as rendered,
    ):
        for kind, i in zip(kinds[order], index[order], strict=True):
            t_host, t_dev = int(host[kind][i]), int(device[kind][i])
            if kind == 0:
                image = to_bgr8(rendered(i), rng_image, config.image_noise, config.exposure_jitter)
                writer.write_camera_info(camera, t_host, t_dev)
                writer.write_frame(Frame(image, t_host, t_dev, "camera"))
            elif kind == 1:
                scan = simulate_scan(run.world, run.motion, run.lidar, run.T_cam_lidar, scan_t[i], rng_scan)
                writer.write_scan(Scan(scan.points, scan.time_s, scan.intensity, t_host, t_dev, "lidar"))
                points_per_scan.append(len(scan.points))
            else:
                writer.write_imu(ImuSample(readings.gyro[i], readings.accel[i], t_host, t_dev, "imu"))
            if kind != 2:
                done += 1
                if progress is not None:
                    progress(done, total)
        write_ground_truth(run, out / "ground_truth", readings)
    return {
        "session": str(out / "session.mcap"),
        "ground_truth": str(out / "ground_truth"),
        "frames": len(frame_t),
        "scans": len(scan_t),
        "imu_samples": len(imu_t),
        "points_per_scan_mean": float(np.mean(points_per_scan)) if points_per_scan else 0.0,
        "duration_s": run.motion.duration_s,
        "session_bytes": (out / "session.mcap").stat().st_size,
    }


@contextmanager
def rendered_ahead(render: Callable[[int], np.ndarray], count: int) -> Iterator[Callable[[int], np.ndarray]]:
    """``rendered(i)``: ``render(i)`` for ``i`` asked in increasing order below ``count``, computed on
    a worker thread up to :data:`FRAMES_AHEAD` items early. A camera frame renders while the caller
    simulates the LiDAR and compresses the session's images and chunks, which lets go of the
    interpreter's lock (two renders at once do not gain: most of a render holds it); rendering draws
    no random numbers, so the session is the same to the byte."""
    pending: dict[int, Future] = {}
    submitted = 0
    with ThreadPoolExecutor(max_workers=1) as pool:

        def rendered(i: int) -> np.ndarray:
            nonlocal submitted
            while submitted < min(count, i + 1 + FRAMES_AHEAD):
                pending[submitted] = pool.submit(render, submitted)
                submitted += 1
            return pending.pop(i).result()

        yield rendered
