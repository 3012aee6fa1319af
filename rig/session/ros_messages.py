"""Conversions between the toolkit's messages and ROS 2 messages (rosbags typestore, CDR).

Stamps: ``header.stamp`` carries ``t_device`` when the sensor has a clock, else ``t_host``; the
MCAP log time always carries ``t_host``. Which clock a channel's stamps use is recorded in the
channel metadata (``stamp_clock``). Point clouds carry fields ``x y z intensity`` (float32) and
``t`` (uint32 nanoseconds after the header stamp, as Ouster drivers write it).
"""

from __future__ import annotations

from functools import cache
from typing import Any

import cv2
import numpy as np
from rosbags.typesys import Stores, get_typestore

from rig.camera import CameraModel
from rig.errors import InputError
from rig.messages import Frame, ImuSample, Scan

IMAGE = "sensor_msgs/msg/Image"
COMPRESSED_IMAGE = "sensor_msgs/msg/CompressedImage"
CAMERA_INFO = "sensor_msgs/msg/CameraInfo"
POINT_CLOUD = "sensor_msgs/msg/PointCloud2"
IMU = "sensor_msgs/msg/Imu"

# PointField datatype codes → numpy dtypes (sensor_msgs/PointField constants).
_FIELD_DTYPES = {1: "i1", 2: "u1", 3: "i2", 4: "u2", 5: "i4", 6: "u4", 7: "f4", 8: "f8"}
_DISTORTION_MODELS = {"plumb_bob": "pinhole", "rational_polynomial": "pinhole", "opencv": "pinhole"}
_FISHEYE_MODELS = ("equidistant", "fisheye", "kannala_brandt")


@cache
def typestore() -> Any:
    """The ROS 2 (Humble) typestore used for every session."""
    return get_typestore(Stores.ROS2_HUMBLE)


def message_definition(msgtype: str) -> str:
    """The ``ros2msg`` schema text of ``msgtype`` (what MCAP readers need to decode it)."""
    return typestore().generate_msgdef(msgtype, ros_version=2)[0]


def serialize(msg: Any) -> bytes:
    return bytes(typestore().serialize_cdr(msg, msg.__msgtype__))


def deserialize(data: bytes, msgtype: str) -> Any:
    return typestore().deserialize_cdr(data, msgtype)


def _header(stamp_ns: int, frame_id: str) -> Any:
    types = typestore().types
    sec, nanosec = divmod(int(stamp_ns), 1_000_000_000)
    return types["std_msgs/msg/Header"](
        stamp=types["builtin_interfaces/msg/Time"](sec=sec, nanosec=nanosec), frame_id=frame_id
    )


def stamp_ns(msg: Any) -> int:
    """``header.stamp`` of a message in integer nanoseconds."""
    return int(msg.header.stamp.sec) * 1_000_000_000 + int(msg.header.stamp.nanosec)


def _stamp(t_host: int, t_device: int | None) -> int:
    return t_host if t_device is None else t_device


def frame_to_msg(frame: Frame, frame_id: str, image_format: str = "jpeg", jpeg_quality: int = 95) -> Any:
    """A ``CompressedImage`` (``image_format`` jpeg/png) or raw ``Image`` (``raw``) of ``frame``."""
    types = typestore().types
    header = _header(_stamp(frame.t_host, frame.t_device), frame_id)
    image = frame.image
    if frame.encoding == "rgb8":
        image = cv2.cvtColor(image, cv2.COLOR_RGB2BGR)
    if image_format == "raw":
        encoding = "mono8" if image.ndim == 2 else "bgr8"
        channels = 1 if image.ndim == 2 else 3
        return types[IMAGE](
            header=header,
            height=image.shape[0],
            width=image.shape[1],
            encoding=encoding,
            is_bigendian=0,
            step=image.shape[1] * channels,
            data=np.ascontiguousarray(image).reshape(-1),
        )
    if image_format not in ("jpeg", "png"):
        raise ValueError(f"unknown image format {image_format!r}; expected jpeg, png or raw")
    params = [cv2.IMWRITE_JPEG_QUALITY, jpeg_quality] if image_format == "jpeg" else []
    ok, encoded = cv2.imencode(".jpg" if image_format == "jpeg" else ".png", image, params)
    if not ok:
        raise ValueError(f"OpenCV could not encode a {image.shape} image as {image_format}")
    return types[COMPRESSED_IMAGE](header=header, format=image_format, data=encoded.reshape(-1))


def msg_to_frame(msg: Any, msgtype: str, t_host: int, t_device: int | None, camera_id: str) -> Frame:
    """A BGR (or mono) :class:`Frame` from an ``Image`` or ``CompressedImage``."""
    if msgtype == COMPRESSED_IMAGE:
        image = cv2.imdecode(np.asarray(msg.data, dtype=np.uint8), cv2.IMREAD_UNCHANGED)
        if image is None:
            raise InputError(f"cannot decode {msg.format!r} image data", field=camera_id)
    elif msgtype == IMAGE:
        channels = {"mono8": 1, "bgr8": 3, "rgb8": 3}.get(msg.encoding)
        if channels is None:
            raise InputError(f"unsupported image encoding {msg.encoding!r}", field=camera_id)
        rows = np.asarray(msg.data, dtype=np.uint8).reshape(msg.height, msg.step)
        image = rows[:, : msg.width * channels].reshape(msg.height, msg.width, channels)
        if msg.encoding == "rgb8":
            image = cv2.cvtColor(image, cv2.COLOR_RGB2BGR)
        image = image[:, :, 0] if channels == 1 else image
    else:
        raise InputError(f"{msgtype} is not an image type", field=camera_id)
    encoding = "mono8" if image.ndim == 2 else "bgr8"
    return Frame(np.ascontiguousarray(image), t_host, t_device, camera_id, encoding)


def camera_to_msg(camera: CameraModel, t_host: int, t_device: int | None, frame_id: str) -> Any:
    """A ``CameraInfo`` describing ``camera``."""
    types = typestore().types
    if camera.model == "fisheye":
        model = "equidistant"
    else:
        model = {0: "plumb_bob", 4: "plumb_bob", 5: "plumb_bob", 8: "rational_polynomial"}.get(
            camera.dist.size, "opencv"
        )
    P = np.zeros((3, 4))
    P[:, :3] = camera.K
    return types[CAMERA_INFO](
        header=_header(_stamp(t_host, t_device), frame_id),
        height=camera.height,
        width=camera.width,
        distortion_model=model,
        d=camera.dist.copy(),
        k=camera.K.reshape(-1).copy(),
        r=np.eye(3).reshape(-1),
        p=P.reshape(-1),
        binning_x=0,
        binning_y=0,
        roi=types["sensor_msgs/msg/RegionOfInterest"](
            x_offset=0, y_offset=0, height=0, width=0, do_rectify=False
        ),
    )


def msg_to_camera(msg: Any) -> CameraModel:
    """A :class:`CameraModel` from a ``CameraInfo``."""
    if msg.distortion_model in _FISHEYE_MODELS:
        model = "fisheye"
    elif msg.distortion_model in _DISTORTION_MODELS or not msg.distortion_model:
        model = "pinhole"
    else:
        raise InputError(
            f"unsupported distortion model {msg.distortion_model!r}; expected plumb_bob, "
            "rational_polynomial or equidistant",
            field="CameraInfo.distortion_model",
        )
    dist = np.asarray(msg.d, dtype=np.float64)
    if model == "pinhole" and dist.size and not np.any(dist):
        dist = np.zeros(0)
    return CameraModel(model, int(msg.width), int(msg.height), np.asarray(msg.k).reshape(3, 3), dist)


def scan_to_msg(scan: Scan, frame_id: str) -> Any:
    """A ``PointCloud2`` with fields x y z intensity (float32) and t (uint32 ns after the stamp)."""
    types = typestore().types
    offsets_ns = np.round(np.asarray(scan.point_time_s, dtype=np.float64) * 1e9)
    if offsets_ns.size and (offsets_ns.min() < 0 or offsets_ns.max() >= 2**32):
        raise ValueError("point times must lie in [0, 4.29 s) after the scan stamp")
    cloud = np.empty(
        len(scan), dtype=[("x", "<f4"), ("y", "<f4"), ("z", "<f4"), ("intensity", "<f4"), ("t", "<u4")]
    )
    cloud["x"], cloud["y"], cloud["z"] = (np.asarray(scan.points, dtype=np.float32)[:, i] for i in range(3))
    cloud["intensity"] = scan.intensity
    cloud["t"] = offsets_ns.astype(np.uint32)
    field = types["sensor_msgs/msg/PointField"]
    fields = [
        field(name=name, offset=cloud.dtype.fields[name][1], datatype=code, count=1)
        for name, code in (("x", 7), ("y", 7), ("z", 7), ("intensity", 7), ("t", 6))
    ]
    return types[POINT_CLOUD](
        header=_header(_stamp(scan.t_host, scan.t_device), frame_id),
        height=1,
        width=len(scan),
        fields=fields,
        is_bigendian=False,
        point_step=cloud.dtype.itemsize,
        row_step=cloud.dtype.itemsize * len(scan),
        data=cloud.view(np.uint8).reshape(-1),
        is_dense=True,
    )


def pointcloud_fields(msg: Any) -> dict[str, np.ndarray]:
    """Every field of a ``PointCloud2`` as a flat ``(height*width,)`` array, by name."""
    order = ">" if msg.is_bigendian else "<"
    names, formats, offsets = [], [], []
    for f in msg.fields:
        if f.datatype not in _FIELD_DTYPES:
            raise InputError(f"unknown PointField datatype {f.datatype} for {f.name!r}", field="PointCloud2")
        names.append(f.name)
        formats.append(
            (order + _FIELD_DTYPES[f.datatype], (f.count,))
            if f.count > 1
            else order + _FIELD_DTYPES[f.datatype]
        )
        offsets.append(f.offset)
    dtype = np.dtype({"names": names, "formats": formats, "offsets": offsets, "itemsize": msg.point_step})
    count = int(msg.height) * int(msg.width)
    rows = np.asarray(msg.data, dtype=np.uint8).reshape(int(msg.height), int(msg.row_step))
    packed = np.ascontiguousarray(rows[:, : int(msg.width) * msg.point_step]).reshape(-1)
    cloud = packed.view(dtype)[:count]
    return {name: np.asarray(cloud[name]) for name in names}


def msg_to_scan(msg: Any, t_host: int, t_device: int | None, lidar_id: str) -> Scan:
    """A :class:`Scan` from a ``PointCloud2`` with x y z and optional intensity / per-point time.

    Per-point time is read from ``t`` (uint ns, Ouster), ``time`` or ``timestamp`` (float s,
    relative to the stamp when small, else absolute); missing fields give zeros.
    """
    fields = pointcloud_fields(msg)
    missing = [k for k in ("x", "y", "z") if k not in fields]
    if missing:
        raise InputError(f"PointCloud2 lacks field(s) {', '.join(missing)}", field=lidar_id)
    points = np.stack([fields["x"], fields["y"], fields["z"]], axis=1).astype(np.float32)
    intensity = fields.get("intensity", fields.get("reflectivity", np.zeros(len(points))))
    if "t" in fields:
        point_time = fields["t"].astype(np.float64) * 1e-9
    elif "time" in fields or "timestamp" in fields:
        raw = fields.get("time", fields.get("timestamp")).astype(np.float64)
        point_time = raw - stamp_ns(msg) * 1e-9 if raw.size and np.abs(raw).max() > 1e6 else raw
    else:
        point_time = np.zeros(len(points))
    finite = np.isfinite(points).all(axis=1)
    return Scan(
        points[finite],
        point_time[finite].astype(np.float32),
        np.asarray(intensity, dtype=np.float32)[finite],
        t_host,
        t_device,
        lidar_id,
    )


def imu_to_msg(sample: ImuSample, frame_id: str) -> Any:
    """An ``Imu`` message (orientation unknown: covariance[0] = -1, as REP 145 asks)."""
    types = typestore().types
    vector = types["geometry_msgs/msg/Vector3"]
    orientation_cov = np.zeros(9)
    orientation_cov[0] = -1.0
    w, a = np.asarray(sample.angular_velocity, float), np.asarray(sample.linear_acceleration, float)
    return types[IMU](
        header=_header(_stamp(sample.t_host, sample.t_device), frame_id),
        orientation=types["geometry_msgs/msg/Quaternion"](x=0.0, y=0.0, z=0.0, w=1.0),
        orientation_covariance=orientation_cov,
        angular_velocity=vector(x=w[0], y=w[1], z=w[2]),
        angular_velocity_covariance=np.zeros(9),
        linear_acceleration=vector(x=a[0], y=a[1], z=a[2]),
        linear_acceleration_covariance=np.zeros(9),
    )


def msg_to_imu(msg: Any, t_host: int, t_device: int | None, imu_id: str) -> ImuSample:
    w, a = msg.angular_velocity, msg.linear_acceleration
    return ImuSample(np.array([w.x, w.y, w.z]), np.array([a.x, a.y, a.z]), t_host, t_device, imu_id)
