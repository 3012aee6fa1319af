"""The virtual rig: simulated camera + LiDAR + IMU recordings of known scenes, with ground truth.

Public API (imported lazily, so that ``lts --help`` does not load open3d)::

    SimConfig            options of a run (scene.yaml stores them)
    simulate(config, out_dir, progress=None) -> summary dict   session.mcap + ground_truth/
    prepare(config) -> SimRun     world, motion, rig and clocks, without writing anything
    record(run, out_dir, progress=None) -> summary dict        writes a prepared run
    World, preset_world, mesh_world, PRESETS, get_preset   (presets: room ... street)
    Mover, inside_movers          moving vehicles and their swept volumes
    Motion, path_motion           continuous-time camera motion
    CameraSimulator               ray-cast images and depth
    LidarModel, simulate_scan     rosette / spinning / Velodyne-like LiDAR sweeps
    ImuModel, simulate_imu        gyro + accelerometer
    SensorClock                   device clocks (offset, drift) and host latency
    preview_image                 a frame with a LiDAR sweep drawn on it
"""

from __future__ import annotations

from rig.lazy import lazy_exports

_EXPORTS = {
    "SimConfig": "rig.sim.config",
    "simulate": "rig.sim.simulate",
    "prepare": "rig.sim.simulate",
    "record": "rig.sim.simulate",
    "SimRun": "rig.sim.simulate",
    "World": "rig.sim.world",
    "preset_world": "rig.sim.world",
    "mesh_world": "rig.sim.world",
    "PRESETS": "rig.sim.scenes",
    "get_preset": "rig.sim.scenes",
    "Mover": "rig.sim.movers",
    "inside_movers": "rig.sim.movers",
    "Motion": "rig.sim.motion",
    "path_motion": "rig.sim.trajectories",
    "CameraSimulator": "rig.sim.camera_sim",
    "LidarModel": "rig.sim.lidar_sim",
    "simulate_scan": "rig.sim.lidar_sim",
    "ImuModel": "rig.sim.imu_sim",
    "simulate_imu": "rig.sim.imu_sim",
    "SensorClock": "rig.sim.clocks",
    "preview_image": "rig.sim.preview",
}
__all__, __getattr__ = lazy_exports(__name__, _EXPORTS)
