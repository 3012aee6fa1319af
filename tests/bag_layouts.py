"""Others' recordings made from a virtual-rig session, for the tests that read foreign bags.

:func:`write_layout` writes a session (``lts sim`` output) as a ROS 1 bag, split ROS 1 bags, a
rosbag2 sqlite3 bag or a rosbag2 MCAP bag, with the topic names, message types, point layouts and
frame ids that real drivers and datasets use (:data:`LAYOUTS`). Every layout has ``/tf_static`` with
the camera and the LiDAR in one tree, built from the session's ground-truth ``calib.yaml``.

Header stamps are the session's host stamps (``t_host``), as ROS drivers stamp in ROS time (the
host's clock; the virtual rig's device clocks differ from each other by minutes), so a reader that
aligns by header stamp gets exactly the stamps the session is read with natively; the bag's receive
time is ``t_host`` plus a fixed transport delay per sensor (:data:`DELAY_NS`). Messages are
converted and written one at a time.
"""

from __future__ import annotations

import dataclasses
import heapq
import sqlite3
from bisect import bisect_right
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from functools import partial
from pathlib import Path
from typing import Any

import cv2
import numpy as np
import yaml
from mcap.writer import CompressionType
from mcap.writer import Writer as McapWriter
from rosbags.rosbag1 import Writer as Ros1Writer
from rosbags.rosbag2 import Writer as Ros2Writer
from rosbags.typesys import Stores, get_types_from_msg, get_typestore
from scipy.spatial.transform import Rotation

from rig.calibration import load_calibration
from rig.messages import Frame, ImuSample, Scan
from rig.session import DEFAULT_TOPICS, UT_MM_TOPICS, SessionReader
from rig.session import ros_messages as rm
from rig.transforms import invert, make_transform, to_quaternion

TF_STATIC = "/tf_static"
TF_MESSAGE = "tf2_msgs/msg/TFMessage"
BASE_FRAME = "base_link"
#: Where the LiDAR sits on the robot in every layout's /tf_static: 10 cm ahead of and 30 cm above
#: ``base_link``, turned 90° about z (so that a reader must compose the tree, not read one edge).
T_BASE_LIDAR = make_transform(Rotation.from_euler("z", 90, degrees=True).as_matrix(), np.array([0.1, 0, 0.3]))
#: Receive time minus sensor time on the host clock, per role (ns): a few ms of transport.
DELAY_NS = {"image": 8_000_000, "camera_info": 8_000_000, "points": 3_000_000, "imu": 1_000_000}
SPLIT_PARTS = 3


def _ros2_types() -> dict[str, Any]:
    return rm.typestore().types


def raw_image_msg(
    pixels: np.ndarray, encoding: str, header: Any, *, row_align: int = 1, bigendian: bool = False
) -> Any:
    """A raw ``Image`` of ``pixels`` ``(H, W[, C])`` (uint8 or uint16, already in ``encoding``), each
    row padded with junk bytes to a multiple of ``row_align`` bytes."""
    height, width = pixels.shape[:2]
    ordered = pixels.astype(pixels.dtype.newbyteorder(">" if bigendian else "<"))
    packed = np.ascontiguousarray(ordered).view(np.uint8).reshape(height, -1)
    step = -(-packed.shape[1] // row_align) * row_align
    rows = np.full((height, step), 0x5A, dtype=np.uint8)
    rows[:, : packed.shape[1]] = packed
    return _ros2_types()[rm.IMAGE](
        header=header,
        height=height,
        width=width,
        encoding=encoding,
        is_bigendian=int(bigendian),
        step=step,
        data=rows.reshape(-1),
    )


def compressed_image_msg(image: np.ndarray, header: Any, fmt: str) -> Any:
    """A ``CompressedImage`` of ``image`` (as OpenCV takes it: BGR, BGRA or grey, 8 or 16 bits)
    with the format string ``fmt``: JPEG (quality 95) when it names jpeg, else PNG."""
    jpeg = "jpeg" in fmt
    ok, data = cv2.imencode(".jpg" if jpeg else ".png", image, [cv2.IMWRITE_JPEG_QUALITY, 95] if jpeg else [])
    assert ok
    return _ros2_types()[rm.COMPRESSED_IMAGE](header=header, format=fmt, data=data.reshape(-1))


def _mono8_msg(image: np.ndarray, header: Any) -> Any:
    return raw_image_msg(cv2.cvtColor(image, cv2.COLOR_BGR2GRAY), "mono8", header)


def _bgr8_padded_msg(image: np.ndarray, header: Any) -> Any:
    return raw_image_msg(image, "bgr8", header, row_align=64)


def cloud_msg(
    header: Any,
    columns: dict[str, tuple[np.ndarray, int, str]],
    point_step: int,
    *,
    rows: int = 1,
    row_padding: int = 0,
    bigendian: bool = False,
) -> Any:
    """A ``PointCloud2`` from ``{field: (values (N,), offset, numpy dtype such as "f4")}``: ``rows``
    rows (organised when more than 1; short rows end in zero points, Ouster's "no return"), each
    followed by ``row_padding`` junk bytes."""
    codes = {dtype: code for code, dtype in rm.POINT_FIELD_DTYPES.items()}
    n = len(next(iter(columns.values()))[0])
    width = max(1, -(-n // rows))
    order = ">" if bigendian else "<"
    dtype = np.dtype(
        {
            "names": list(columns),
            "formats": [order + c[2] for c in columns.values()],
            "offsets": [c[1] for c in columns.values()],
            "itemsize": point_step,
        }
    )
    cloud = np.zeros(rows * width, dtype=dtype)
    for name, (values, *_) in columns.items():
        cloud[name][:n] = values
    data = np.full((rows, width * point_step + row_padding), 0x5A, dtype=np.uint8)
    data[:, : width * point_step] = cloud.view(np.uint8).reshape(rows, -1)
    field = _ros2_types()["sensor_msgs/msg/PointField"]
    return _ros2_types()[rm.POINT_CLOUD](
        header=header,
        height=rows,
        width=width,
        fields=[field(name=name, offset=c[1], datatype=codes[c[2]], count=1) for name, c in columns.items()],
        is_bigendian=bigendian,
        point_step=point_step,
        row_step=width * point_step + row_padding,
        data=data.reshape(-1),
        is_dense=rows == 1,
    )


def xyz_columns(points: np.ndarray) -> dict[str, tuple[np.ndarray, int, str]]:
    """Fields x y z (float32 at offsets 0, 4, 8) of ``points`` ``(N, 3)``."""
    points = np.asarray(points, dtype=np.float32)
    return {axis: (points[:, i], 4 * i, "f4") for i, axis in enumerate("xyz")}


def _ouster_cloud(scan: Scan, header: Any, rows: int) -> Any:
    """Ouster's point layout (ouster-ros ``ouster_ros::Point``): x y z, padding, intensity, ``t``
    (uint32 ns after the stamp), reflectivity, ring, ambient, range (mm); 48 bytes a point."""
    n = len(scan)
    columns = xyz_columns(scan.points) | {
        "intensity": (scan.intensity, 16, "f4"),
        "t": (np.round(np.asarray(scan.point_time_s, np.float64) * 1e9), 20, "u4"),
        "reflectivity": (np.clip(scan.intensity, 0, 65535), 24, "u2"),
        "ring": (np.arange(n) % rows, 26, "u2"),
        "ambient": (np.zeros(n), 28, "u2"),
        "range": (np.linalg.norm(scan.points, axis=1) * 1000, 32, "u4"),
    }
    return cloud_msg(header, columns, 48, rows=rows)


def _velodyne_cloud(scan: Scan, header: Any) -> Any:
    """velodyne_pointcloud's PointXYZIRT: x y z intensity (float32), ring (uint16), ``time``
    (float32 s relative to the stamp), packed into 22 bytes."""
    columns = xyz_columns(scan.points) | {
        "intensity": (scan.intensity, 12, "f4"),
        "ring": (np.zeros(len(scan)), 16, "u2"),
        "time": (scan.point_time_s, 18, "f4"),
    }
    return cloud_msg(header, columns, 22)


def livox_custom_msg(scan: Scan, header: Any, msgtype: str = "livox_ros_driver2/msg/CustomMsg") -> Any:
    """A Livox ``CustomMsg`` of ``msgtype`` (ROS 2 types): ``timebase`` = the scan's stamp,
    ``offset_time`` ns after it, intensity rounded into ``reflectivity``."""
    types = _ros2_types()
    point = types[msgtype.replace("CustomMsg", "CustomPoint")]
    offsets = np.round(np.asarray(scan.point_time_s, np.float64) * 1e9).astype(np.uint32)
    reflectivity = np.clip(np.round(scan.intensity), 0, 255).astype(np.uint8)
    points = [
        point(
            offset_time=int(t),
            x=float(p[0]),
            y=float(p[1]),
            z=float(p[2]),
            reflectivity=int(r),
            tag=0,
            line=0,
        )
        for t, p, r in zip(offsets, scan.points, reflectivity, strict=True)
    ]
    return types[msgtype](
        header=header,
        timebase=rm.sensor_stamp(scan.t_host, scan.t_device),
        point_num=len(points),
        lidar_id=0,
        rsvd=np.zeros(3, dtype=np.uint8),
        points=points,
    )


@dataclass(frozen=True)
class Layout:
    """One bag layout: where each role is published and how.

    Attributes:
        storage: ``bag`` (one ROS 1 file), ``split`` (:data:`SPLIT_PARTS` ROS 1 files), ``sqlite3``
            (rosbag2 as ROS 2 Humble wrote it: no message definitions) or ``mcap`` (rosbag2).
        topics: ``{role: topic}`` for image, camera_info, points, imu.
        frame_ids: ``{role: frame id}`` for camera, lidar, imu.
        image: ``(BGR image (H, W, 3), header) -> ROS 2 image message``.
        cloud: ``(Scan, header) -> ROS 2 point-cloud message``.
    """

    storage: str
    topics: dict[str, str]
    frame_ids: dict[str, str]
    image: Callable[[np.ndarray, Any], Any]
    cloud: Callable[[Scan, Any], Any]


# ouster-ros frame ids (os_lidar, os_imu) and realsense-ros optical frame names; the ROS 1
# compressed_image_transport writes "<raw encoding>; jpeg compressed bgr8".
_UTMM = Layout(
    storage="bag",
    topics=UT_MM_TOPICS,
    frame_ids={"camera": "camera_color_optical_frame", "lidar": "os_lidar", "imu": "os_imu"},
    image=partial(compressed_image_msg, fmt="rgb8; jpeg compressed bgr8"),
    cloud=partial(_ouster_cloud, rows=1),
)
LAYOUTS: dict[str, Layout] = {
    "utmm": _UTMM,
    "utmm_split": dataclasses.replace(_UTMM, storage="split"),
    # Newer College 2020 (Ouster OS1-64 + RealSense D435i infrared): the Ouster topics as evalio
    # reads the bags (github.com/contagon/evalio, python/evalio/datasets/newer_college_2020.py), the
    # camera topics as realsense-ros names the left infrared stream; frame ids of the OS1-era
    # ouster_ros driver. Ouster clouds are organised (here 16 rows, short rows padded with zeros).
    "newer_college": Layout(
        storage="bag",
        topics={
            "image": "/camera/infra1/image_rect_raw",
            "camera_info": "/camera/infra1/camera_info",
            "points": "/os1_cloud_node/points",
            "imu": "/os1_cloud_node/imu",
        },
        frame_ids={"camera": "camera_infra1_optical_frame", "lidar": "os1_lidar", "imu": "os1_imu"},
        image=_mono8_msg,
        cloud=partial(_ouster_cloud, rows=16),
    ),
    # livox_ros_driver2's topics and frame (src/lddc.cpp: livox/lidar, livox/imu; launch_ROS2/
    # msg_MID360_launch.py: livox_frame); raw bgr8 rows padded to 64 bytes, as some camera drivers do.
    "livox_ros2": Layout(
        storage="sqlite3",
        topics={
            "image": "/camera/image_raw",
            "camera_info": "/camera/camera_info",
            "points": "/livox/lidar",
            "imu": "/livox/imu",
        },
        frame_ids={"camera": "camera_optical_frame", "lidar": "livox_frame", "imu": "livox_frame"},
        image=_bgr8_padded_msg,
        cloud=livox_custom_msg,
    ),
    # velodyne_pointcloud's default topic and frame; ROS 2 image_transport's compressed format.
    "velodyne_ros2_mcap": Layout(
        storage="mcap",
        topics={
            "image": "/camera/image_raw/compressed",
            "camera_info": "/camera/camera_info",
            "points": "/velodyne_points",
            "imu": "/imu/data",
        },
        frame_ids={"camera": "camera_optical_frame", "lidar": "velodyne", "imu": "imu_link"},
        image=partial(compressed_image_msg, fmt="bgr8; jpeg compressed bgr8"),
        cloud=_velodyne_cloud,
    ),
}


def ros1_typestore() -> Any:
    """ROS 1 Noetic types plus tf2_msgs/TFMessage (which rosbags' Noetic store lacks)."""
    store = get_typestore(Stores.ROS1_NOETIC)
    store.register(get_types_from_msg("geometry_msgs/TransformStamped[] transforms", TF_MESSAGE))
    return store


def to_ros1(msg: Any, store: Any) -> Any:
    """The ROS 1 version of a ROS 2 message: the same fields, ``seq`` 0 in headers, CameraInfo's
    upper-case ``D K R P``."""
    cls = store.types[msg.__msgtype__]
    values = {}
    for field in dataclasses.fields(cls):
        if field.name == "__msgtype__":
            continue
        value = 0 if field.name == "seq" else getattr(msg, field.name, None)
        if value is None:
            value = getattr(msg, field.name.lower())
        if hasattr(value, "__msgtype__"):
            value = to_ros1(value, store)
        elif isinstance(value, list):
            value = [to_ros1(v, store) if hasattr(v, "__msgtype__") else v for v in value]
        values[field.name] = value
    return cls(**values)


class _Ros1Bags:
    """ROS 1 bag files written one after the other (``part`` only grows)."""

    def __init__(self, paths: list[Path]) -> None:
        self.store = ros1_typestore()
        self._paths = paths
        self._part = -1
        self._writer: Any = None
        self._connections: dict[str, Any] = {}

    def write(self, topic: str, msg: Any, log_time: int, part: int = 0) -> None:
        while self._part < part:
            self._next_file()
        connection = self._connections.get(topic)
        if connection is None:
            connection = self._writer.add_connection(
                topic, msg.__msgtype__, typestore=self.store, latching=int(topic == TF_STATIC)
            )
            self._connections[topic] = connection
        ros1 = to_ros1(msg, self.store)
        self._writer.write(connection, log_time, bytes(self.store.serialize_ros1(ros1, msg.__msgtype__)))

    def _next_file(self) -> None:
        self.close()
        self._part += 1
        self._writer = Ros1Writer(self._paths[self._part])
        self._writer.open()
        self._connections = {}

    def close(self) -> None:
        if self._writer is not None:
            self._writer.close()
            self._writer = None


class _Rosbag2Sqlite:
    """A rosbag2 sqlite3 bag as ROS 2 Humble writes it: metadata version 5, no stored message
    definitions (so a reader must know every type, Livox CustomMsg included, by itself)."""

    def __init__(self, path: Path) -> None:
        self._path = path
        self._writer = Ros2Writer(path)
        self._writer.open()
        self._connections: dict[str, Any] = {}

    def write(self, topic: str, msg: Any, log_time: int, part: int = 0) -> None:
        connection = self._connections.get(topic)
        if connection is None:
            connection = self._writer.add_connection(topic, msg.__msgtype__, typestore=rm.typestore())
            self._connections[topic] = connection
        self._writer.write(connection, log_time, rm.serialize(msg))

    def close(self) -> None:
        self._writer.close()
        with sqlite3.connect(self._path / f"{self._path.name}.db3") as db:
            db.execute("DROP TABLE message_definitions")
            db.execute("UPDATE schema SET schema_version = 3")
        meta_path = self._path / "metadata.yaml"
        meta = yaml.safe_load(meta_path.read_text())
        info = meta["rosbag2_bagfile_information"]
        info["version"] = 5
        for key in ("custom_data", "ros_distro"):
            info.pop(key, None)
        for topic in info["topics_with_message_count"]:
            topic["topic_metadata"].pop("type_description_hash", None)
        meta_path.write_text(yaml.safe_dump(meta, sort_keys=False))


class _Rosbag2Mcap:
    """A rosbag2 bag with MCAP storage (one ``.mcap`` file and ``metadata.yaml``), as ``ros2 bag
    record -s mcap`` writes it: ros2 profile, ``ros2msg`` schemas, CDR messages."""

    def __init__(self, path: Path) -> None:
        path.mkdir(parents=True)
        self._path = path
        self._file_name = f"{path.name}_0.mcap"
        self._file = (path / self._file_name).open("wb")
        self._writer = McapWriter(self._file, compression=CompressionType.ZSTD)
        self._writer.start(profile="ros2", library="tests/bag_layouts.py")
        self._schemas: dict[str, int] = {}
        self._channels: dict[str, int] = {}
        self._topics: dict[str, list[Any]] = {}  # topic: [msgtype, count]
        self._times: list[int] = []

    def write(self, topic: str, msg: Any, log_time: int, part: int = 0) -> None:
        msgtype = msg.__msgtype__
        if msgtype not in self._schemas:
            definition = rm.message_definition(msgtype).encode()
            self._schemas[msgtype] = self._writer.register_schema(msgtype, "ros2msg", definition)
        if topic not in self._channels:
            self._channels[topic] = self._writer.register_channel(
                topic, "cdr", self._schemas[msgtype], {"offered_qos_profiles": ""}
            )
            self._topics[topic] = [msgtype, 0]
        self._writer.add_message(self._channels[topic], log_time, rm.serialize(msg), log_time)
        self._topics[topic][1] += 1
        self._times.append(log_time)

    def close(self) -> None:
        self._writer.finish()
        self._file.close()
        start, end, count = min(self._times), max(self._times), len(self._times)
        span = {"starting_time": {"nanoseconds_since_epoch": start}, "duration": {"nanoseconds": end - start}}
        info = {
            "version": 8,
            "storage_identifier": "mcap",
            "relative_file_paths": [self._file_name],
            **span,
            "message_count": count,
            "topics_with_message_count": [
                {
                    "topic_metadata": {
                        "name": topic,
                        "type": msgtype,
                        "serialization_format": "cdr",
                        "offered_qos_profiles": "",
                    },
                    "message_count": n,
                }
                for topic, (msgtype, n) in self._topics.items()
            ],
            "compression_format": "",
            "compression_mode": "",
            "files": [{"path": self._file_name, **span, "message_count": count}],
        }
        (self._path / "metadata.yaml").write_text(
            yaml.safe_dump({"rosbag2_bagfile_information": info}, sort_keys=False)
        )


def _transform_msg(T_parent_child: np.ndarray, parent: str, child: str, stamp: int) -> Any:
    types = _ros2_types()
    x, y, z = T_parent_child[:3, 3]
    qx, qy, qz, qw = to_quaternion(T_parent_child)
    return types["geometry_msgs/msg/TransformStamped"](
        header=rm.make_header(stamp, parent),
        child_frame_id=child,
        transform=types["geometry_msgs/msg/Transform"](
            translation=types["geometry_msgs/msg/Vector3"](x=x, y=y, z=z),
            rotation=types["geometry_msgs/msg/Quaternion"](x=qx, y=qy, z=qz, w=qw),
        ),
    )


def tf_static_msg(T_cam_lidar: np.ndarray, frame_ids: dict[str, str], stamp: int) -> Any:
    """``/tf_static``: ``base_link`` → LiDAR (:data:`T_BASE_LIDAR`), → camera (through
    ``T_cam_lidar`` ``(4, 4)``) and → IMU (on the LiDAR frame, as in the virtual rig)."""
    T_base_camera = T_BASE_LIDAR @ invert(T_cam_lidar)
    children = {
        frame_ids["lidar"]: T_BASE_LIDAR,
        frame_ids["camera"]: T_base_camera,
        frame_ids["imu"]: T_BASE_LIDAR,
    }
    transforms = [_transform_msg(T, BASE_FRAME, child, stamp) for child, T in children.items()]
    return _ros2_types()[TF_MESSAGE](transforms=transforms)


def _session_stream(reader: SessionReader) -> Iterator[tuple[str, Frame | Scan | ImuSample]]:
    """``(role, message)`` of the session's camera, LiDAR and IMU in host-time order, stamped by the
    host clock only (``t_device`` None)."""
    streams = [
        (("image", m) for m in reader.frames(DEFAULT_TOPICS["image"])),
        (("points", m) for m in reader.scans(DEFAULT_TOPICS["points"])),
        (("imu", m) for m in reader.imu(DEFAULT_TOPICS["imu"])),
    ]
    for role, message in heapq.merge(*streams, key=lambda item: item[1].t_host):
        yield role, dataclasses.replace(message, t_device=None)


def _open_bag(layout: Layout, path: Path) -> _Ros1Bags | _Rosbag2Sqlite | _Rosbag2Mcap:
    if layout.storage == "bag":
        return _Ros1Bags([path])
    if layout.storage == "split":
        path.mkdir(parents=True)
        return _Ros1Bags([path / f"{path.name}_{i}.bag" for i in range(SPLIT_PARTS)])
    return _Rosbag2Sqlite(path) if layout.storage == "sqlite3" else _Rosbag2Mcap(path)


def write_layout(session_mcap: Path, out: Path, layout: str) -> Path:
    """Write the session ``session_mcap`` (beside its ``ground_truth/calib.yaml``) into folder
    ``out`` in one of :data:`LAYOUTS`.

    Returns the recording: ``out/LAYOUT.bag`` (ROS 1), the rosbag2 folder ``out/LAYOUT``, or for
    ``split`` storage the folder ``out/LAYOUT`` holding ``LAYOUT_0.bag`` … in time order (each file
    is cut at a third of the session's host-time span; ``/tf_static`` is in the first).
    """
    spec = LAYOUTS[layout]
    reader = SessionReader(session_mcap)
    calibration = load_calibration(Path(session_mcap).parent / "ground_truth" / "calib.yaml")
    camera = reader.camera_model(DEFAULT_TOPICS["camera_info"])
    spans = reader.topics().values()
    start, end = min(s.first_t for s in spans), max(s.last_t for s in spans)
    cuts = [start + (end - start) * i // SPLIT_PARTS for i in range(1, SPLIT_PARTS)]
    out.mkdir(parents=True, exist_ok=True)
    path = out / (f"{layout}.bag" if spec.storage == "bag" else layout)
    bag = _open_bag(spec, path)
    try:
        bag.write(TF_STATIC, tf_static_msg(calibration.T_cam_lidar, spec.frame_ids, start), start)
        for role, item in _session_stream(reader):
            part = bisect_right(cuts, item.t_host) if spec.storage == "split" else 0
            stamp = rm.sensor_stamp(item.t_host, item.t_device)
            log_time = item.t_host + DELAY_NS[role]
            topic = spec.topics[role]
            if role == "image":
                header = rm.make_header(stamp, spec.frame_ids["camera"])
                bag.write(topic, spec.image(item.image, header), log_time, part)
                info = rm.camera_to_msg(camera, item.t_host, item.t_device, spec.frame_ids["camera"])
                bag.write(spec.topics["camera_info"], info, item.t_host + DELAY_NS["camera_info"], part)
            elif role == "points":
                bag.write(
                    topic, spec.cloud(item, rm.make_header(stamp, spec.frame_ids["lidar"])), log_time, part
                )
            else:
                bag.write(topic, rm.imu_to_msg(item, spec.frame_ids["imu"]), log_time, part)
    finally:
        bag.close()
    return path
