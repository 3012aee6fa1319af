"""calib: camera intrinsics, LiDAR–camera extrinsics and camera–LiDAR time offset.

The calibration file format itself (:class:`rig.Calibration`) lives in ``rig`` with the other
shared data types.
"""
