"""calib: camera intrinsics, LiDAR–camera extrinsics and camera–LiDAR time offset.

The calibration file format itself (:class:`rig.Calibration`) lives in ``rig`` with the other
shared data types. Public API:

- boards and intrinsics: :class:`ChessboardTarget`, :class:`CharucoTarget`, :func:`detect_views`,
  :func:`calibrate_intrinsics` → :class:`IntrinsicsResult`;
- targetless extrinsic: from image + cloud pairs, :class:`ExtrinsicPair`, :func:`refine_extrinsic`
  → :class:`ExtrinsicResult`; from a recording's LiDAR map (:func:`build_lidar_map` →
  :class:`LidarMap`) seen in many frames, :class:`ConsistencyFrame`,
  :func:`photo_consistency_extrinsic`;
- board extrinsic: :class:`BoardObservation`, :func:`board_observations`, :func:`calibrate_with_board`;
- time offset: :func:`estimate_time_offset` → :class:`TimeOffsetResult` (from angular velocities);
- sessions: :func:`calibrate_session` (time offset, then the extrinsic from a rough guess: from a
  chessboard, :class:`BoardGeometry` / :func:`board_geometry`, or targetless);
- quality pictures: :func:`write_comparison`.
"""

from calib.board_session import BoardGeometry, board_geometry
from calib.boards import BoardView, CharucoTarget, ChessboardTarget, detect_views
from calib.intrinsics import IntrinsicsResult, calibrate_intrinsics
from calib.lidar_map import LidarMap, build_lidar_map
from calib.overlay import write_comparison
from calib.photo_consistency import ConsistencyFrame, photo_consistency_extrinsic
from calib.session_calib import calibrate_session
from calib.target_based import BoardObservation, board_observations, calibrate_with_board
from calib.targetless import ExtrinsicPair, ExtrinsicResult, refine_extrinsic
from calib.time_offset import TimeOffsetResult, estimate_time_offset

__all__ = [
    "BoardGeometry",
    "BoardObservation",
    "BoardView",
    "CharucoTarget",
    "ChessboardTarget",
    "ConsistencyFrame",
    "ExtrinsicPair",
    "ExtrinsicResult",
    "IntrinsicsResult",
    "LidarMap",
    "TimeOffsetResult",
    "board_geometry",
    "board_observations",
    "build_lidar_map",
    "calibrate_intrinsics",
    "calibrate_session",
    "calibrate_with_board",
    "detect_views",
    "estimate_time_offset",
    "photo_consistency_extrinsic",
    "refine_extrinsic",
    "write_comparison",
]
