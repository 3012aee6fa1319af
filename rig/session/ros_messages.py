"""Conversions between the toolkit's messages and ROS 2 messages (rosbags typestore, CDR).

Stamps: ``header.stamp`` carries ``t_device`` when the sensor has a clock, else ``t_host``; the
MCAP log time always carries ``t_host``. Which clock a channel's stamps use is recorded in the
channel metadata (``stamp_clock``). Point clouds carry fields ``x y z intensity`` (float32) and
``t`` (uint32 nanoseconds after the header stamp, as Ouster drivers write it).

Reading accepts what others' bags hold: raw images in the ``sensor_msgs`` encodings of
:data:`ROS_IMAGE_ENCODINGS`, jpeg/png ``CompressedImage`` (image_transport's format strings too),
``PointCloud2`` with the per-point time of Ouster, Velodyne, Hesai or Livox drivers, and Livox
``CustomMsg`` (:mod:`rig.session.livox_messages`).
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
from rig.session.livox_messages import CUSTOM_MSG_TYPES, custom_msg_to_scan, register_livox_types

IMAGE = "sensor_msgs/msg/Image"
COMPRESSED_IMAGE = "sensor_msgs/msg/CompressedImage"
CAMERA_INFO = "sensor_msgs/msg/CameraInfo"
POINT_CLOUD = "sensor_msgs/msg/PointCloud2"
IMU = "sensor_msgs/msg/Imu"
#: Message types read as LiDAR sweeps.
POINT_CLOUD_TYPES = (POINT_CLOUD, *CUSTOM_MSG_TYPES)

#: PointField datatype codes → numpy dtypes (sensor_msgs/PointField constants).
POINT_FIELD_DTYPES = {1: "i1", 2: "u1", 3: "i2", 4: "u2", 5: "i4", 6: "u4", 7: "f4", 8: "f8"}
_DISTORTION_MODELS = {"plumb_bob": "pinhole", "rational_polynomial": "pinhole", "opencv": "pinhole"}
_FISHEYE_MODELS = ("equidistant", "fisheye", "kannala_brandt")


@cache
def typestore() -> Any:
    """The ROS 2 (Humble) typestore used for every session, with the Livox ``CustomMsg`` types
    (which bags without embedded definitions need)."""
    store = get_typestore(Stores.ROS2_HUMBLE)
    register_livox_types(store)
    return store


def message_definition(msgtype: str) -> str:
    """The ``ros2msg`` schema text of ``msgtype`` (what MCAP readers need to decode it)."""
    return typestore().generate_msgdef(msgtype, ros_version=2)[0]


def serialize(msg: Any) -> bytes:
    return bytes(typestore().serialize_cdr(msg, msg.__msgtype__))


def deserialize(data: bytes, msgtype: str) -> Any:
    return typestore().deserialize_cdr(data, msgtype)


def make_header(stamp_ns: int, frame_id: str) -> Any:
    """A ROS 2 ``std_msgs/Header`` stamped ``stamp_ns`` (ns)."""
    types = typestore().types
    sec, nanosec = divmod(int(stamp_ns), 1_000_000_000)
    return types["std_msgs/msg/Header"](
        stamp=types["builtin_interfaces/msg/Time"](sec=sec, nanosec=nanosec), frame_id=frame_id
    )


def stamp_ns(msg: Any) -> int:
    """``header.stamp`` of a message in integer nanoseconds."""
    return int(msg.header.stamp.sec) * 1_000_000_000 + int(msg.header.stamp.nanosec)


def sensor_stamp(t_host: int, t_device: int | None) -> int:
    """The header stamp of a message: its device time when the sensor has a clock, else host time."""
    return t_host if t_device is None else t_device


def frame_to_msg(frame: Frame, frame_id: str, image_format: str = "jpeg", jpeg_quality: int = 95) -> Any:
    """A ``CompressedImage`` (``image_format`` jpeg/png) or raw ``Image`` (``raw``) of ``frame``."""
    types = typestore().types
    header = make_header(sensor_stamp(frame.t_host, frame.t_device), frame_id)
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


def _image_encodings() -> dict[str, tuple[int, int, int | None]]:
    """``{encoding: (channels, bits per channel, OpenCV conversion to BGR or None)}``."""
    table: dict[str, tuple[int, int, int | None]] = {"8UC1": (1, 8, None), "8UC3": (3, 8, None)}
    for bits in (8, 16):
        table |= {
            f"mono{bits}": (1, bits, None),
            f"bgr{bits}": (3, bits, None),
            f"rgb{bits}": (3, bits, cv2.COLOR_RGB2BGR),
            f"bgra{bits}": (4, bits, cv2.COLOR_BGRA2BGR),
            f"rgba{bits}": (4, bits, cv2.COLOR_RGBA2BGR),
        }
        for pattern in ("rggb", "bggr", "gbrg", "grbg"):
            table[f"bayer_{pattern}{bits}"] = (1, bits, getattr(cv2, f"COLOR_Bayer{pattern.upper()}2BGR"))
    return table


#: Raw ``Image`` encodings read (sensor_msgs/image_encodings.h names), as channels, bits per
#: channel and the OpenCV conversion to BGR (Bayer patterns are demosaiced).
ROS_IMAGE_ENCODINGS = _image_encodings()
_COMPRESSED_CODECS = ("jpeg", "jpg", "png")


def _to_frame_pixels(pixels: np.ndarray, encoding: str) -> np.ndarray:
    """``(H, W, 3)`` BGR or ``(H, W)`` grey uint8 from ``pixels`` ``(H, W[, C])`` in ``encoding``.

    16-bit data keeps its high byte (``v >> 8``): one fixed mapping for every frame, so brightness
    stays comparable across a sequence (per-frame stretching would flicker and break photometric
    losses), and an 8-bit image widened by ×257 comes back exactly. 10/12-bit sensors stored in 16
    bits therefore come out dark rather than stretched.
    """
    channels, _, code = ROS_IMAGE_ENCODINGS[encoding]
    if channels == 1 and pixels.ndim == 3:
        pixels = pixels[:, :, 0]
    image = pixels if code is None else cv2.cvtColor(np.ascontiguousarray(pixels), code)
    if image.dtype == np.uint16:
        image = (image >> 8).astype(np.uint8)
    return np.ascontiguousarray(image)


def _raw_pixels(msg: Any, camera_id: str) -> np.ndarray:
    """The pixels ``(H, W, C)`` (uint8 or native uint16) of an ``Image``, row padding removed."""
    spec = ROS_IMAGE_ENCODINGS.get(msg.encoding)
    if spec is None:
        raise InputError(
            f"unsupported image encoding {msg.encoding!r}; expected one of {', '.join(ROS_IMAGE_ENCODINGS)}",
            field=camera_id,
        )
    channels, bits, _ = spec
    height, width, step = int(msg.height), int(msg.width), int(msg.step)
    row_bytes = width * channels * bits // 8
    data = np.asarray(msg.data, dtype=np.uint8)
    if step < row_bytes or data.size < height * step:
        raise InputError(
            f"{msg.encoding} image of {width}x{height} with step {step} needs {height} rows of at least "
            f"{row_bytes} bytes; got step {step} and {data.size} bytes",
            field=camera_id,
        )
    rows = np.ascontiguousarray(data[: height * step].reshape(height, step)[:, :row_bytes])
    if bits == 16:
        rows = rows.view(">u2" if msg.is_bigendian else "<u2").astype(np.uint16)
    return rows.reshape(height, width, channels)


def _compressed_encoding(fmt: str, camera_id: str) -> str | None:
    """The encoding of the compressed pixels where a ``CompressedImage`` format states it
    (image_transport's ``"rgb8; jpeg compressed bgr8"``); refuses formats other than jpeg or png."""
    if "compresseddepth" in fmt.lower():
        raise InputError(
            f"format {fmt!r} is a compressed depth image; expected a camera image in jpeg or png",
            field=camera_id,
        )
    words = fmt.split(";")[-1].split()
    codec = words[0].lower() if words else ""
    if codec and codec not in _COMPRESSED_CODECS:
        raise InputError(
            f"unsupported CompressedImage format {fmt!r}; expected jpeg or png "
            "(optionally as 'ENCODING; jpeg compressed ENCODING')",
            field=camera_id,
        )
    return words[2] if len(words) >= 3 and words[1] == "compressed" else None


def _compressed_pixels(msg: Any, camera_id: str) -> tuple[np.ndarray, str]:
    """The decoded pixels of a ``CompressedImage`` and their encoding."""
    target = _compressed_encoding(msg.format, camera_id)
    image = cv2.imdecode(np.asarray(msg.data, dtype=np.uint8), cv2.IMREAD_UNCHANGED)
    if image is None or image.dtype not in (np.uint8, np.uint16):
        raise InputError(f"cannot decode {msg.format!r} image data", field=camera_id)
    channels = 1 if image.ndim == 2 else image.shape[2]
    bits = 8 * image.dtype.itemsize
    decoded = {1: "mono", 3: "bgr", 4: "bgra"}.get(channels)
    if decoded is None:
        raise InputError(f"{msg.format!r} image decodes to {channels} channels", field=camera_id)
    if target is not None and ROS_IMAGE_ENCODINGS.get(target, (0, 0, None))[:2] == (channels, bits):
        return image, target  # e.g. rgb8 pixels compressed as they were: decoded in RGB order
    return image, f"{decoded}{bits}"


def msg_to_frame(msg: Any, msgtype: str, t_host: int, t_device: int | None, camera_id: str) -> Frame:
    """A BGR (or mono) :class:`Frame` from an ``Image`` (any of :data:`ROS_IMAGE_ENCODINGS`) or a jpeg/png
    ``CompressedImage``; ``camera_id`` (the topic) names the source in errors."""
    if msgtype == COMPRESSED_IMAGE:
        pixels, encoding = _compressed_pixels(msg, camera_id)
    elif msgtype == IMAGE:
        pixels, encoding = _raw_pixels(msg, camera_id), msg.encoding
    else:
        raise InputError(f"{msgtype} is not an image type", field=camera_id)
    image = _to_frame_pixels(pixels, encoding)
    return Frame(image, t_host, t_device, camera_id, "mono8" if image.ndim == 2 else "bgr8")


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
        header=make_header(sensor_stamp(t_host, t_device), frame_id),
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
    """A :class:`CameraModel` from a ROS 2 or ROS 1 ``CameraInfo`` (ROS 1 names ``D`` and ``K``)."""
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
    dist = np.asarray(msg.d if hasattr(msg, "d") else msg.D, dtype=np.float64)
    K = np.asarray(msg.k if hasattr(msg, "k") else msg.K, dtype=np.float64).reshape(3, 3)
    if model == "pinhole" and dist.size and not np.any(dist):
        dist = np.zeros(0)
    return CameraModel(model, int(msg.width), int(msg.height), K, dist)


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
        header=make_header(sensor_stamp(scan.t_host, scan.t_device), frame_id),
        height=1,
        width=len(scan),
        fields=fields,
        is_bigendian=False,
        point_step=cloud.dtype.itemsize,
        row_step=cloud.dtype.itemsize * len(scan),
        data=cloud.view(np.uint8).reshape(-1),
        is_dense=True,
    )


def pointcloud_fields(msg: Any, lidar_id: str) -> dict[str, np.ndarray]:
    """Every field of a ``PointCloud2`` as a flat ``(height*width,)`` array, by name (row padding of
    organised clouds removed); ``lidar_id`` (the topic) names the source in errors."""
    order = ">" if msg.is_bigendian else "<"
    height, width, point_step, row_step = (
        int(v) for v in (msg.height, msg.width, msg.point_step, msg.row_step)
    )
    names, formats, offsets = [], [], []
    for f in msg.fields:
        if f.datatype not in POINT_FIELD_DTYPES:
            raise InputError(f"unknown PointField datatype {f.datatype} for {f.name!r}", field=lidar_id)
        dtype = np.dtype(order + POINT_FIELD_DTYPES[f.datatype])
        if f.offset + dtype.itemsize * max(1, f.count) > point_step:
            raise InputError(
                f"field {f.name!r} at offset {f.offset} does not fit a point of {point_step} bytes",
                field=lidar_id,
            )
        names.append(f.name)
        formats.append((dtype, (f.count,)) if f.count > 1 else dtype)
        offsets.append(f.offset)
    data = np.asarray(msg.data, dtype=np.uint8)
    if row_step < width * point_step or data.size < height * row_step:
        raise InputError(
            f"{height} rows of {width} points of {point_step} bytes need row_step >= {width * point_step} "
            f"and {height * row_step} bytes; got row_step {row_step} and {data.size} bytes",
            field=lidar_id,
        )
    dtype = np.dtype({"names": names, "formats": formats, "offsets": offsets, "itemsize": point_step})
    rows = data[: height * row_step].reshape(height, row_step)
    cloud = np.ascontiguousarray(rows[:, : width * point_step]).reshape(-1).view(dtype)
    return {name: np.asarray(cloud[name]) for name in names}


def _relative_seconds(values: np.ndarray, stamp: int) -> np.ndarray:
    """Per-point times ``(N,)`` in seconds after the header ``stamp`` (ns) from a float time field
    that may hold seconds relative to the stamp (Velodyne ``time``, negative when the driver stamps
    the end of the sweep), absolute seconds (Hesai and RoboSense ``timestamp``) or absolute
    nanoseconds (livox_ros_driver2 ``timestamp``, src/lddc.cpp): the reading that puts the sweep
    nearest the stamp wins."""
    values = values.astype(np.float64)
    finite = values[np.isfinite(values)]
    if finite.size == 0:
        return values
    sec, nsec = divmod(stamp, 1_000_000_000)
    readings = (
        lambda v: v,
        lambda v: (v - sec) - nsec * 1e-9,
        lambda v: (v - stamp) * 1e-9,
    )
    middle = float(np.median(finite))
    return min(readings, key=lambda reading: abs(reading(middle)))(values)


def _point_times_s(fields: dict[str, np.ndarray], stamp: int, count: int) -> np.ndarray:
    """Per-point times ``(N,)`` in seconds after the header stamp: Ouster ``t`` and Livox
    ``offset_time`` are nanoseconds after it; ``time`` / ``timestamp`` see :func:`_relative_seconds`;
    zeros when the cloud has no time field."""
    for name in ("t", "offset_time"):
        if name in fields:
            return fields[name].astype(np.float64) * 1e-9
    for name in ("time", "timestamp"):
        if name in fields:
            return _relative_seconds(fields[name], stamp)
    return np.zeros(count)


def msg_to_scan(msg: Any, t_host: int, t_device: int | None, lidar_id: str) -> Scan:
    """A :class:`Scan` from a ``PointCloud2`` (x y z, optional intensity or reflectivity and
    per-point time, see :func:`_point_times_s`) or a Livox ``CustomMsg``.

    Point times are relative to the message's header stamp. Points that are not finite (organised
    clouds mark missing returns with NaN) or exactly at the origin (Ouster's "no return") are
    dropped.
    """
    if getattr(msg, "__msgtype__", None) in CUSTOM_MSG_TYPES:
        return custom_msg_to_scan(msg, t_host, t_device, lidar_id)
    fields = pointcloud_fields(msg, lidar_id)
    missing = [k for k in ("x", "y", "z") if k not in fields]
    if missing:
        raise InputError(f"PointCloud2 lacks field(s) {', '.join(missing)}", field=lidar_id)
    points = np.stack([fields["x"], fields["y"], fields["z"]], axis=1).astype(np.float32)
    intensity = fields.get("intensity", fields.get("reflectivity", np.zeros(len(points))))
    point_time = _point_times_s(fields, stamp_ns(msg), len(points))
    keep = np.isfinite(points).all(axis=1) & points.any(axis=1)
    return Scan(
        points[keep],
        point_time[keep].astype(np.float32),
        np.asarray(intensity, dtype=np.float32)[keep],
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
        header=make_header(sensor_stamp(sample.t_host, sample.t_device), frame_id),
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
