"""Sensor messages: camera frames, LiDAR scans and IMU samples.

Every message carries ``t_host`` (host monotonic clock, ``time.monotonic_ns()`` compatible) and
``t_device`` (the sensor's own clock, None when the device has none), both integer nanoseconds.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from rig.errors import InputError

IMAGE_ENCODINGS = ("bgr8", "rgb8", "mono8")


@dataclass(eq=False)
class Frame:
    """One camera image.

    Attributes:
        image: ``(H, W, 3)`` uint8 colour (see ``encoding``) or ``(H, W)`` uint8 grey.
        t_host, t_device: capture time in ns on the host and on the device clock.
        camera_id: which camera took it (a device id or a topic-like name).
        encoding: ``bgr8`` (OpenCV order, the default), ``rgb8`` or ``mono8``.
    """

    image: np.ndarray
    t_host: int
    t_device: int | None
    camera_id: str
    encoding: str = "bgr8"

    def __post_init__(self) -> None:
        if self.encoding not in IMAGE_ENCODINGS:
            raise InputError(
                f"unknown encoding {self.encoding!r}; expected one of {IMAGE_ENCODINGS}",
                field="encoding",
            )
        expected_ndim = 2 if self.encoding == "mono8" else 3
        if self.image.ndim != expected_ndim or (expected_ndim == 3 and self.image.shape[2] != 3):
            raise InputError(
                f"image of shape {self.image.shape} does not match encoding {self.encoding}",
                field="image",
            )
        if self.image.dtype != np.uint8:
            raise InputError(f"expected a uint8 image, got {self.image.dtype}", field="image")

    @property
    def height(self) -> int:
        return int(self.image.shape[0])

    @property
    def width(self) -> int:
        return int(self.image.shape[1])


@dataclass(eq=False)
class Scan:
    """One LiDAR sweep in the LiDAR frame.

    Attributes:
        points: ``(N, 3)`` float32/float64 x, y, z in metres.
        point_time_s: ``(N,)`` float32/float64 time of each point in seconds relative to the
            scan stamp (``t_device`` / ``t_host``), usually in ``[0, sweep period)``.
        intensity: ``(N,)`` float32 return intensity (units of the sensor, or simulated reflectivity).
        t_host, t_device: scan stamp in ns (the start of the sweep).
        lidar_id: which LiDAR produced it.
    """

    points: np.ndarray
    point_time_s: np.ndarray
    intensity: np.ndarray
    t_host: int
    t_device: int | None
    lidar_id: str = "lidar"

    def __post_init__(self) -> None:
        n = len(self.points)
        if self.points.ndim != 2 or self.points.shape[1] != 3:
            raise InputError(f"expected points of shape (N, 3), got {self.points.shape}", field="points")
        for name in ("point_time_s", "intensity"):
            value = getattr(self, name)
            if value.shape != (n,):
                raise InputError(f"expected shape ({n},), got {value.shape}", field=name)

    def __len__(self) -> int:
        return len(self.points)

    def point_times_ns(self, *, host: bool = False) -> np.ndarray:
        """Absolute per-point times ``(N,)`` int64 ns on the device (or host) clock."""
        stamp = self.t_host if host or self.t_device is None else self.t_device
        return stamp + np.round(np.asarray(self.point_time_s, dtype=np.float64) * 1e9).astype(np.int64)


@dataclass(eq=False)
class ImuSample:
    """One IMU reading in the IMU frame.

    Attributes:
        angular_velocity: ``(3,)`` rad/s.
        linear_acceleration: ``(3,)`` m/s² (specific force, gravity included).
        t_host, t_device: sample time in ns.
        imu_id: which IMU produced it.
    """

    angular_velocity: np.ndarray
    linear_acceleration: np.ndarray
    t_host: int
    t_device: int | None
    imu_id: str = "imu"
