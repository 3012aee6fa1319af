"""rig: where data is born — sensor data model, sessions, drivers and the virtual rig.

The data model below imports without any hardware library; drivers import their vendor library
lazily when opened.
"""

from rig.calibration import Calibration, load_calibration, save_calibration
from rig.camera import CameraModel
from rig.deskew import deskewed_points
from rig.errors import InputError, OutOfRangeError
from rig.image_io import read_image
from rig.messages import Frame, ImuSample, Scan
from rig.pointcloud_io import PointCloud, read_point_cloud
from rig.trajectory import Trajectory
from rig.trajectory_io import (
    FORMATS as TRAJECTORY_FORMATS,
)
from rig.trajectory_io import (
    detect_format,
    read_euroc,
    read_kitti,
    read_matrix_lines,
    read_trajectory,
    read_tum,
    write_euroc,
    write_kitti,
    write_matrix_lines,
    write_trajectory,
    write_tum,
)
from rig.transforms import (
    check_rigid,
    distance_and_angle,
    from_quaternion,
    invert,
    make_transform,
    to_quaternion,
    transform_points,
)

__all__ = [
    "TRAJECTORY_FORMATS",
    "Calibration",
    "CameraModel",
    "Frame",
    "ImuSample",
    "InputError",
    "OutOfRangeError",
    "PointCloud",
    "Scan",
    "Trajectory",
    "check_rigid",
    "deskewed_points",
    "detect_format",
    "distance_and_angle",
    "from_quaternion",
    "invert",
    "load_calibration",
    "make_transform",
    "read_euroc",
    "read_image",
    "read_kitti",
    "read_matrix_lines",
    "read_point_cloud",
    "read_trajectory",
    "read_tum",
    "save_calibration",
    "to_quaternion",
    "transform_points",
    "write_euroc",
    "write_kitti",
    "write_matrix_lines",
    "write_trajectory",
    "write_tum",
]
