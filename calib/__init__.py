"""calib: camera intrinsics, LiDAR–camera extrinsics and camera–LiDAR time offset.

The calibration file format itself (:class:`rig.Calibration`) lives in ``rig`` with the other
shared data types. Public API:

- boards and intrinsics: :class:`ChessboardTarget`, :class:`CharucoTarget`, :func:`detect_views`,
  :func:`calibrate_intrinsics` → :class:`IntrinsicsResult`;
- targetless extrinsic: :class:`ExtrinsicPair`, :func:`refine_extrinsic` → :class:`ExtrinsicResult`;
- quality pictures: :func:`write_comparison`;
- point clouds: :func:`read_point_cloud` (PCD ascii/binary/binary_compressed, KITTI ``.bin``).
"""

from calib.boards import BoardView, CharucoTarget, ChessboardTarget, detect_views
from calib.intrinsics import IntrinsicsResult, calibrate_intrinsics
from calib.overlay import write_comparison
from calib.pointcloud_io import PointCloud, read_point_cloud
from calib.targetless import ExtrinsicPair, ExtrinsicResult, pose_difference, refine_extrinsic

__all__ = [
    "BoardView",
    "CharucoTarget",
    "ChessboardTarget",
    "ExtrinsicPair",
    "ExtrinsicResult",
    "IntrinsicsResult",
    "PointCloud",
    "calibrate_intrinsics",
    "detect_views",
    "pose_difference",
    "read_point_cloud",
    "refine_extrinsic",
    "write_comparison",
]
