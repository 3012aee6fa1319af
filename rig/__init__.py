"""rig: where data is born — sensor data model, sessions, drivers and the virtual rig.

The data model imports without any hardware library; drivers import their vendor library
lazily when opened. Names are imported on first use (PEP 562), so that every command line
(``lts --help`` too) does not load SciPy's spatial module before it needs it.
"""

from __future__ import annotations

from rig.lazy import lazy_exports

_EXPORTS = {
    "Calibration": "rig.calibration",
    "load_calibration": "rig.calibration",
    "save_calibration": "rig.calibration",
    "CameraModel": "rig.camera",
    "cpu_threads": "rig.cpu_threads",
    "deskewed_points": "rig.deskew",
    "InputError": "rig.errors",
    "OutOfRangeError": "rig.errors",
    "read_image": "rig.image_io",
    "Frame": "rig.messages",
    "ImuSample": "rig.messages",
    "Scan": "rig.messages",
    "PointCloud": "rig.pointcloud_io",
    "read_point_cloud": "rig.pointcloud_io",
    "RegisteredSweep": "rig.sweep_registration",
    "RegistrationLog": "rig.sweep_registration",
    "SweepSettings": "rig.sweep_registration",
    "registered_sweeps": "rig.sweep_registration",
    "Trajectory": "rig.trajectory",
    "detect_format": "rig.trajectory_io",
    "read_euroc": "rig.trajectory_io",
    "read_kitti": "rig.trajectory_io",
    "read_matrix_lines": "rig.trajectory_io",
    "read_trajectory": "rig.trajectory_io",
    "read_tum": "rig.trajectory_io",
    "write_euroc": "rig.trajectory_io",
    "write_kitti": "rig.trajectory_io",
    "write_matrix_lines": "rig.trajectory_io",
    "write_trajectory": "rig.trajectory_io",
    "write_tum": "rig.trajectory_io",
    "TRAJECTORY_FORMATS": "rig.trajectory_io:FORMATS",
    "check_rigid": "rig.transforms",
    "distance_and_angle": "rig.transforms",
    "from_quaternion": "rig.transforms",
    "invert": "rig.transforms",
    "make_transform": "rig.transforms",
    "to_quaternion": "rig.transforms",
    "transform_points": "rig.transforms",
}
__all__, __getattr__ = lazy_exports(__name__, _EXPORTS)
