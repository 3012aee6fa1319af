"""Assembling 2D LiDAR revolutions from packets/nodes into :class:`~rig.messages.Scan` messages."""

from __future__ import annotations

import numpy as np

from rig.messages import Scan


class RevolutionAssembler:
    """Collects the points of one revolution; :meth:`add` returns the previous one when a new one starts.

    Points are 2D (z = 0) in the LiDAR frame, x forward at angle 0; angles turn clockwise seen
    from above (LDROBOT and Slamtec both do), so ``y = -r sin(angle)``. Point times are absolute ns
    on one clock (device clock when the sensor has one, else host); the scan stamp is the first
    point's time and ``stamp_to_host`` turns it into ``t_host``.
    """

    def __init__(self, lidar_id: str, device_clock: bool) -> None:
        self.lidar_id = lidar_id
        self.device_clock = device_clock
        self._parts: list[tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]] = []
        self._t_host0 = 0
        self._partial = True  # the revolution being collected began mid-turn

    def discard(self) -> None:
        """Forget the revolution in progress (after a disconnect); the next one starts mid-turn."""
        self._parts.clear()
        self._partial = True

    def add(
        self,
        new_revolution: bool,
        angle_deg: np.ndarray,
        distance_m: np.ndarray,
        intensity: np.ndarray,
        t_ns: np.ndarray,
        t_host0: int,
    ) -> Scan | None:
        """Add ``(N,)`` points; ``t_host0`` is the host time of the first. Returns the finished
        revolution when ``new_revolution`` is set and a whole one was in progress (the first,
        partial revolution after start or a disconnect is dropped)."""
        done = None
        if new_revolution and self._parts:
            done = None if self._partial else self._finish()
            self._parts.clear()
        if new_revolution:
            self._partial = False
        if not self._parts:
            self._t_host0 = t_host0
        self._parts.append((angle_deg, distance_m, intensity, t_ns))
        return done

    def _finish(self) -> Scan:
        angle, dist, inten, t = (np.concatenate(a) for a in zip(*self._parts, strict=True))
        keep = dist > 0
        rad = np.deg2rad(angle[keep])
        r = dist[keep]
        points = np.stack([r * np.cos(rad), -r * np.sin(rad), np.zeros_like(r)], axis=1).astype(np.float32)
        stamp = int(t[0])
        return Scan(
            points,
            ((t[keep] - stamp) * 1e-9).astype(np.float32),
            inten[keep].astype(np.float32),
            t_host=self._t_host0,
            t_device=stamp if self.device_clock else None,
            lidar_id=self.lidar_id,
        )
