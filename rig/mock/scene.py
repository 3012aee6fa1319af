"""A virtual-rig scene (``SCENE_DIR/session.mcap``) as streams of timed messages.

Mock devices replay the simulated frames, scans and IMU samples in real time: each stream yields
``(t_rel_ns, message)`` with ``t_rel_ns`` the simulated host time since the first message of the
session, repeating each stream (shifted by its count times its period) when a recording outlasts
the session, unless the scene is played once.
"""

from __future__ import annotations

from collections.abc import Callable, Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from rig.camera import CameraModel
from rig.errors import InputError
from rig.messages import Frame, ImuSample, Scan
from rig.session import ros_messages as rm
from rig.session.reader import SessionReader

_ROLE_TYPES = {
    "image": (rm.IMAGE, rm.COMPRESSED_IMAGE),
    "points": (rm.POINT_CLOUD,),
    "imu": (rm.IMU,),
    "camera_info": (rm.CAMERA_INFO,),
}


@dataclass(frozen=True)
class StreamInfo:
    topic: str
    count: int
    first_t: int
    last_t: int

    @property
    def rate_hz(self) -> float:
        return (self.count - 1) / ((self.last_t - self.first_t) / 1e9) if self.count > 1 else 0.0

    @property
    def period_ns(self) -> int:
        return round(1e9 / self.rate_hz) if self.rate_hz else 0


class Scene:
    """The streams of a simulated session, found by message type; ``once``: each stream ends after
    one pass instead of repeating."""

    def __init__(self, scene_dir: str | Path, once: bool = False) -> None:
        self.dir = Path(scene_dir)
        self.once = once
        self.session = self.dir / "session.mcap" if self.dir.is_dir() else self.dir
        if not self.session.is_file():
            raise InputError("no session.mcap in the scene folder (expected `lts sim` output)", path=self.dir)
        self.reader = SessionReader(self.session)
        topics = self.reader.topics()
        self.streams: dict[str, StreamInfo] = {}
        for role, types in _ROLE_TYPES.items():
            for name, t in topics.items():
                if t.msgtype in types and role not in self.streams:
                    self.streams[role] = StreamInfo(name, t.count, t.first_t, t.last_t)
        if "image" not in self.streams and "points" not in self.streams:
            raise InputError("the scene's session has neither images nor point clouds", path=self.session)
        self.t0 = min(s.first_t for s in self.streams.values())
        self.span_ns = max(s.last_t for s in self.streams.values()) - self.t0

    def rates(self) -> dict[str, float]:
        """Simulated rate of each role in Hz."""
        return {role: s.rate_hz for role, s in self.streams.items() if role != "camera_info"}

    def camera(self) -> CameraModel | None:
        info = self.streams.get("camera_info")
        return None if info is None else self.reader.camera_model(info.topic)

    def _loop(self, role: str) -> Iterator[tuple[int, Any]]:
        info = self.streams[role]
        # Each stream repeats after count x period, so its rate holds across the seam. Streams
        # then shift against each other by under one period per lap (e.g. 91 frames at 30 Hz vs
        # 601 IMU samples at 200 Hz): simulate a scene as long as the recording where the timing
        # between streams matters beyond the first lap.
        lap_ns = info.count * info.period_ns if info.count > 1 else self.span_ns + 1
        lap = 0
        while lap == 0 or not self.once:
            for m in self.reader.messages([info.topic]):
                t_rel = m.t_host - self.t0 + lap * lap_ns
                if role == "image":
                    yield t_rel, rm.msg_to_frame(m.msg, m.msgtype, m.t_host, m.t_device, info.topic)
                elif role == "points":
                    yield t_rel, rm.msg_to_scan(m.msg, m.t_host, m.t_device, info.topic)
                else:
                    yield t_rel, rm.msg_to_imu(m.msg, m.t_host, m.t_device, info.topic)
            lap += 1

    def frames(self) -> Iterator[tuple[int, Frame]]:
        return self._loop("image")

    def scans(self) -> Iterator[tuple[int, Scan]]:
        return self._loop("points")

    def imu(self) -> Iterator[tuple[int, ImuSample]]:
        return self._loop("imu")


def slice_2d(scan: Scan, n_bins: int = 450, max_elevation_deg: float = 2.0) -> tuple[np.ndarray, np.ndarray]:
    """A 2D LiDAR's view of a 3D scan: nearest range per angle bin among near-horizontal points.

    Returns ``(n_bins,)`` range in metres (0 = no return) and ``(n_bins,)`` intensity, bin ``i``
    at angle ``i * 360 / n_bins`` degrees, clockwise from +x seen from above (the 2D LiDARs' sense).
    """
    p = np.asarray(scan.points, dtype=np.float64)
    r_xy = np.hypot(p[:, 0], p[:, 1])
    flat = (np.abs(np.degrees(np.arctan2(p[:, 2], r_xy))) <= max_elevation_deg) & (r_xy > 0.05)
    angle = np.degrees(np.arctan2(-p[flat, 1], p[flat, 0])) % 360.0
    bins = np.minimum((angle / 360.0 * n_bins).astype(np.int64), n_bins - 1)
    ranges = np.full(n_bins, np.inf)
    np.minimum.at(ranges, bins, r_xy[flat])
    intensity = np.zeros(n_bins)
    hit = np.isfinite(ranges)
    ranges[~hit] = 0.0
    intensity[hit] = 200.0
    return ranges, intensity


def latest_slice(scans: Iterator[tuple[int, Scan]]) -> Callable[[int], tuple[np.ndarray, np.ndarray]]:
    """``revolution(t_rel_ns)``: the 2D slice of the newest scan at that time (for a fake 2D LiDAR)."""
    state: dict[str, Any] = {"next": next(scans, None)}
    empty = (np.zeros(450), np.zeros(450))
    state["current"] = slice_2d(state["next"][1]) if state["next"] is not None else empty

    def revolution(t_rel_ns: int) -> tuple[np.ndarray, np.ndarray]:
        while state["next"] is not None and state["next"][0] <= t_rel_ns:
            state["current"] = slice_2d(state["next"][1])
            state["next"] = next(scans, None)
        return state["current"]

    return revolution
