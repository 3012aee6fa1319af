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

Names are imported on first use (PEP 562), so that ``lts --help``, which imports this package,
does not load SciPy's statistics and OpenCV's calibration code.
"""

from __future__ import annotations

from rig.lazy import lazy_exports

_EXPORTS = {
    "BoardGeometry": "calib.board_session",
    "board_geometry": "calib.board_session",
    "BoardView": "calib.boards",
    "CharucoTarget": "calib.boards",
    "ChessboardTarget": "calib.boards",
    "detect_views": "calib.boards",
    "IntrinsicsResult": "calib.intrinsics",
    "calibrate_intrinsics": "calib.intrinsics",
    "LidarMap": "calib.lidar_map",
    "build_lidar_map": "calib.lidar_map",
    "write_comparison": "calib.overlay",
    "ConsistencyFrame": "calib.photo_consistency",
    "photo_consistency_extrinsic": "calib.photo_consistency",
    "calibrate_session": "calib.session_calib",
    "BoardObservation": "calib.target_based",
    "board_observations": "calib.target_based",
    "calibrate_with_board": "calib.target_based",
    "ExtrinsicPair": "calib.targetless",
    "ExtrinsicResult": "calib.targetless",
    "refine_extrinsic": "calib.targetless",
    "TimeOffsetResult": "calib.time_offset",
    "estimate_time_offset": "calib.time_offset",
}
__all__, __getattr__ = lazy_exports(__name__, _EXPORTS)
