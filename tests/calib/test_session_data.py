"""LiDAR points around camera frames (calib.session_data) when a session has no LiDAR scans."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from calib.session_calib import extrinsic_pairs
from calib.session_data import SessionData, frame_clouds
from rig.messages import Frame


def _frames_only(n: int = 40) -> SessionData:
    image = np.zeros((12, 16, 3), dtype=np.uint8)
    frames = [Frame(image, 1_000_000_000 + k * 33_000_000, None, "camera") for k in range(n)]
    return SessionData(frames, [], [], None, Path("frames_only.mcap"))


def test_no_scans_give_no_clouds_and_no_pairs() -> None:
    data = _frames_only()
    assert frame_clouds(data, [0, 5, 39], 0.015) == [None, None, None]
    assert extrinsic_pairs(data, 0.015) == []
