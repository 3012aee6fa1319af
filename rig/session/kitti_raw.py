"""KITTI raw "sync" drives read in place as a recording: ``…/2011_09_26_drive_NNNN_sync/`` with
``image_0X/`` (rectified PNGs and ``timestamps.txt``), ``velodyne_points/`` (``.bin`` sweeps,
``timestamps.txt``, ``timestamps_start.txt``, ``timestamps_end.txt``), optional ``oxts/``, and
``calib_cam_to_cam.txt`` + ``calib_velo_to_cam.txt`` in the drive folder or its parent.

The drive reads as a bag would: one topic per camera (``/kitti/camera_0X/image``, PNG
``CompressedImage``, and its ``camera_info``), ``/kitti/velodyne/points``, ``/kitti/oxts/imu`` and a
``/tf_static`` joining the Velodyne to each rectified camera, so that the folder's calibration is
the recording's (``--calib tf``; the start of ``lts calibrate`` without ``--init``), as a bag's
``/tf_static`` is. The file layout and the calibration fields follow the KITTI raw data
development kit's readme (Geiger et al., IJRR 2013).
"""

from __future__ import annotations

import logging
import re
from collections.abc import Iterable, Iterator
from dataclasses import dataclass
from datetime import UTC, datetime
from functools import cached_property
from pathlib import Path
from typing import Any

import cv2
import numpy as np

from rig.camera import CameraModel
from rig.errors import InputError
from rig.image_io import read_image
from rig.messages import Frame, ImuSample, Scan
from rig.session import ros_messages as rm
from rig.session.source import Recording, SessionMessage, TimeSpan, TopicSummary
from rig.transforms import invert, make_transform, to_quaternion

log = logging.getLogger(__name__)

FORMAT = "KITTI raw"
POINTS_TOPIC = "/kitti/velodyne/points"
IMU_TOPIC = "/kitti/oxts/imu"
TF_STATIC = "/tf_static"
LIDAR_FRAME = "velodyne"
#: KITTI's colour cameras (0 and 1 are grey).
COLOUR_CAMERAS = (2, 3)
_OXTS_ACCELERATION = slice(14, 17)  # af, al, au (m/s², forward/left/up: the IMU frame's axes)
_OXTS_ANGULAR_RATE = slice(20, 23)  # wf, wl, wu (rad/s)
_OXTS_FIELDS = 30


def image_topic(camera: int) -> str:
    return f"/kitti/camera_{camera:02d}/image"


def camera_info_topic(camera: int) -> str:
    return f"/kitti/camera_{camera:02d}/camera_info"


def is_kitti_drive(path: Path) -> bool:
    """Whether ``path`` is a folder laid out as a KITTI raw drive (``velodyne_points/`` beside an
    ``image_0X/``)."""
    return path.is_dir() and (path / "velodyne_points").is_dir() and any(path.glob("image_0[0-3]"))


def parse_stamps(path: Path) -> np.ndarray:
    """Times ``(N,)`` int64 ns of a KITTI ``timestamps*.txt`` (``YYYY-MM-DD HH:MM:SS.fffffffff``,
    taken as UTC; the fraction's digits are kept exactly)."""
    if not path.is_file():
        raise InputError("missing: the drive has no timestamps for these files", path=path)
    stamps = []
    for number, line in enumerate(path.read_text().splitlines(), start=1):
        if not line.strip():
            continue
        match = re.fullmatch(r"\s*(\d{4}-\d\d-\d\d \d\d:\d\d:\d\d)(?:\.(\d{1,9}))?\s*", line)
        if match is None:
            raise InputError(
                f"line {number}: {line.strip()!r} is not a time 'YYYY-MM-DD HH:MM:SS.fffffffff'", path=path
            )
        seconds = datetime.strptime(match[1], "%Y-%m-%d %H:%M:%S").replace(tzinfo=UTC).timestamp()
        fraction = (match[2] or "").ljust(9, "0")
        stamps.append(int(seconds) * 1_000_000_000 + int(fraction))
    return np.array(stamps, dtype=np.int64)


def _calib_fields(path: Path) -> dict[str, np.ndarray]:
    fields = {}
    for line in path.read_text().splitlines():
        key, sep, values = line.partition(":")
        if not sep:
            continue
        try:
            fields[key.strip()] = np.array([float(v) for v in values.split()])
        except ValueError:
            continue  # calib_time and other text fields
    return fields


def _field(fields: dict[str, np.ndarray], path: Path, key: str, size: int) -> np.ndarray:
    if key not in fields:
        raise InputError(f"missing; expected {size} numbers", path=path, field=key)
    if fields[key].size != size:
        raise InputError(f"expected {size} numbers, got {fields[key].size}", path=path, field=key)
    return fields[key]


def _rotation(matrix: np.ndarray, path: Path, key: str) -> np.ndarray:
    """The rotation nearest the 3×3 ``matrix`` (KITTI prints 7 digits), refused when far from one."""
    R = matrix.reshape(3, 3)
    u, _, vt = np.linalg.svd(R)
    nearest = u @ vt
    if np.linalg.det(nearest) < 0 or np.abs(nearest - R).max() > 1e-3:
        raise InputError("expected a rotation matrix (9 numbers, row-major)", path=path, field=key)
    return nearest


def _calibration_file(drive: Path, name: str) -> Path:
    for folder in (drive, drive.parent):
        if (folder / name).is_file():
            return folder / name
    raise InputError(
        f"no {name} in the drive folder or its parent (KITTI ships it with the day's drives)", path=drive
    )


@dataclass(frozen=True)
class KittiCamera:
    """One rectified KITTI camera: its number, pinhole model and ``T_cam_velo`` (4, 4)."""

    number: int
    model: CameraModel
    T_cam_velo: np.ndarray


def kitti_cameras(drive: Path, numbers: Iterable[int]) -> dict[int, KittiCamera]:
    """The rectified cameras ``numbers`` of ``drive`` from its calibration files: intrinsics from
    ``P_rect_0X`` and ``S_rect_0X``, and ``T_camX_velo = [I | K⁻¹ P_rect_0X[:, 3]] · R_rect_00 ·
    [R | T]`` (the devkit's projection ``P_rect_0X · R_rect_00 · Tr_velo_to_cam``)."""
    cam_path = _calibration_file(drive, "calib_cam_to_cam.txt")
    velo_path = _calibration_file(drive, "calib_velo_to_cam.txt")
    cam, velo = _calib_fields(cam_path), _calib_fields(velo_path)
    T_cam0_velo = make_transform(
        _rotation(_field(velo, velo_path, "R", 9), velo_path, "R"), _field(velo, velo_path, "T", 3)
    )
    rect = make_transform(
        _rotation(_field(cam, cam_path, "R_rect_00", 9), cam_path, "R_rect_00"), np.zeros(3)
    )
    cameras = {}
    for number in numbers:
        P = _field(cam, cam_path, f"P_rect_{number:02d}", 12).reshape(3, 4)
        width, height = _field(cam, cam_path, f"S_rect_{number:02d}", 2)
        K = P[:, :3]
        if K[0, 0] <= 0 or K[1, 1] <= 0 or width < 1 or height < 1:
            raise InputError(
                "expected positive focal lengths and image size", path=cam_path, field=f"P_rect_{number:02d}"
            )
        baseline = make_transform(np.eye(3), np.linalg.solve(K, P[:, 3]))
        model = CameraModel("pinhole", round(width), round(height), K.copy(), np.zeros(0))
        cameras[number] = KittiCamera(number, model, baseline @ rect @ T_cam0_velo)
    return cameras


def point_times(points: np.ndarray, start_ns: int, end_ns: int) -> np.ndarray:
    """Seconds ``(N,)`` after ``start_ns`` at which each point ``(N, 3)`` of a sweep was measured.

    KITTI's ``.bin`` has no point times. The HDL-64E turns clockwise seen from above and a sweep
    runs from straight behind (``timestamps_start``) through the front, where it triggers the
    cameras (``timestamps.txt``), back to behind (``timestamps_end``); a point's share of the sweep
    follows from its azimuth.
    """
    share = 0.5 * (1.0 - np.arctan2(points[:, 1], points[:, 0]) / np.pi)
    return share * ((end_ns - start_ns) * 1e-9)


@dataclass(frozen=True)
class _Entry:
    """One message of the drive: its time (ns), topic and the index of its file on that topic."""

    t: int
    topic: str
    index: int


class KittiRecording(Recording):
    """A KITTI raw sync drive read in place (see the module docstring for its topics).

    Args:
        drive: the ``…_drive_NNNN_sync`` folder.
        span: the part every reader sees; topic_map: ``{role: topic}`` (the image defaults to the
            first colour camera present).
        camera: which camera's images are the ``image`` role (0–3); overrides the topic map.
    """

    def __init__(
        self,
        drive: Path,
        *,
        span: TimeSpan | None = None,
        topic_map: dict[str, str] | None = None,
        camera: int | None = None,
    ) -> None:
        self.path = Path(drive)
        self.format = FORMAT
        self.span = span
        present = sorted(int(p.name[-1]) for p in self.path.glob("image_0[0-3]") if p.is_dir())
        if camera is not None and camera not in present:
            raise InputError(
                f"no image_{camera:02d} folder; the drive has cameras {', '.join(map(str, present))}",
                path=self.path,
                field="--camera",
            )
        default = (
            camera if camera is not None else next((c for c in COLOUR_CAMERAS if c in present), present[0])
        )
        self.topic_map = {"image": image_topic(default), **(topic_map or {})}
        if camera is not None:
            self.topic_map["image"] = image_topic(camera)
        self.camera_numbers = present

    # -- files -------------------------------------------------------------------------------

    def _stamped_files(self, folder: Path, pattern: str) -> tuple[list[Path], np.ndarray]:
        files = sorted((folder / "data").glob(pattern))
        stamps = parse_stamps(folder / "timestamps.txt")
        if len(files) != stamps.size:
            raise InputError(
                f"{len(files)} {pattern} files in data/ but {stamps.size} times in timestamps.txt; "
                "expected one time per file",
                path=folder,
            )
        if np.any(np.diff(stamps) <= 0):
            raise InputError("times in timestamps.txt go backwards or repeat", path=folder / "timestamps.txt")
        return files, stamps

    @cached_property
    def _images(self) -> dict[int, tuple[list[Path], np.ndarray]]:
        return {n: self._stamped_files(self.path / f"image_{n:02d}", "*.png") for n in self.camera_numbers}

    @cached_property
    def _sweeps(self) -> tuple[list[Path], np.ndarray, np.ndarray]:
        """The ``.bin`` files and each sweep's start and end (ns)."""
        folder = self.path / "velodyne_points"
        files, mid = self._stamped_files(folder, "*.bin")
        if (folder / "timestamps_start.txt").is_file() and (folder / "timestamps_end.txt").is_file():
            start, end = (
                parse_stamps(folder / "timestamps_start.txt"),
                parse_stamps(folder / "timestamps_end.txt"),
            )
            for name, stamps in (("timestamps_start.txt", start), ("timestamps_end.txt", end)):
                if stamps.size != mid.size:
                    raise InputError(
                        f"{stamps.size} times but {mid.size} sweeps; expected one per sweep",
                        path=folder / name,
                    )
            if np.any(end <= start):
                raise InputError("a sweep ends before it starts", path=folder / "timestamps_end.txt")
        else:
            period = int(np.median(np.diff(mid))) if mid.size > 1 else 100_000_000
            log.info(
                "%s: no timestamps_start/end.txt; each sweep taken as %.0f ms around its time",
                folder,
                period / 1e6,
            )
            start, end = mid - period // 2, mid + period - period // 2
        return files, start, end

    @cached_property
    def _oxts(self) -> tuple[list[Path], np.ndarray] | None:
        folder = self.path / "oxts"
        return self._stamped_files(folder, "*.txt") if folder.is_dir() else None

    @cached_property
    def cameras(self) -> dict[int, KittiCamera]:
        """Every camera of the drive with its rectified model and extrinsic."""
        return kitti_cameras(self.path, self.camera_numbers)

    @cached_property
    def _index(self) -> list[_Entry]:
        """Every message of the whole drive in time order."""
        entries = []
        for n, (_, stamps) in self._images.items():
            entries += [_Entry(int(t), image_topic(n), i) for i, t in enumerate(stamps)]
            entries.append(_Entry(int(stamps[0]), camera_info_topic(n), 0))
        _, start, _ = self._sweeps
        entries += [_Entry(int(t), POINTS_TOPIC, i) for i, t in enumerate(start)]
        if self._oxts is not None:
            entries += [_Entry(int(t), IMU_TOPIC, i) for i, t in enumerate(self._oxts[1])]
        entries.append(_Entry(min(e.t for e in entries), TF_STATIC, 0))
        return sorted(entries, key=lambda e: (e.t, e.topic))

    def _entries(self, topics: Iterable[str] | None, whole: bool) -> Iterator[_Entry]:
        wanted = None if topics is None else set(topics)
        first, stop = (None, None) if whole or self.span is None else self.span.window(self._index[0].t)
        for entry in self._index:
            if (
                (wanted is None or entry.topic in wanted)
                and (first is None or entry.t >= first)
                and (stop is None or entry.t < stop)
            ):
                yield entry

    # -- messages ----------------------------------------------------------------------------

    def _msgtype(self, topic: str) -> str:
        if topic == POINTS_TOPIC:
            return rm.POINT_CLOUD
        if topic == IMU_TOPIC:
            return rm.IMU
        if topic == TF_STATIC:
            return "tf2_msgs/msg/TFMessage"
        return rm.CAMERA_INFO if topic.endswith("camera_info") else rm.COMPRESSED_IMAGE

    def _camera_of(self, topic: str) -> int:
        return int(topic.split("/")[2][-2:])

    def _message(self, entry: _Entry) -> Any:
        topic = entry.topic
        if topic == POINTS_TOPIC:
            return rm.scan_to_msg(self._scan(entry.index), LIDAR_FRAME)
        if topic == IMU_TOPIC:
            return rm.imu_to_msg(self._imu_sample(entry.index), "oxts")
        if topic == TF_STATIC:
            return self._tf_message(entry.t)
        number = self._camera_of(topic)
        frame_id = f"camera_{number:02d}"
        if topic.endswith("camera_info"):
            return rm.camera_to_msg(self.cameras[number].model, entry.t, None, frame_id)
        path = self._images[number][0][entry.index]
        return rm.typestore().types[rm.COMPRESSED_IMAGE](
            header=rm.make_header(entry.t, frame_id), format="png", data=np.fromfile(path, dtype=np.uint8)
        )

    def _tf_message(self, t: int) -> Any:
        types = rm.typestore().types
        transforms = []
        for number, camera in self.cameras.items():
            T_velo_cam = invert(camera.T_cam_velo)
            q, p = to_quaternion(T_velo_cam), T_velo_cam[:3, 3]
            transforms.append(
                types["geometry_msgs/msg/TransformStamped"](
                    header=rm.make_header(t, LIDAR_FRAME),
                    child_frame_id=f"camera_{number:02d}",
                    transform=types["geometry_msgs/msg/Transform"](
                        translation=types["geometry_msgs/msg/Vector3"](x=p[0], y=p[1], z=p[2]),
                        rotation=types["geometry_msgs/msg/Quaternion"](x=q[0], y=q[1], z=q[2], w=q[3]),
                    ),
                )
            )
        return types["tf2_msgs/msg/TFMessage"](transforms=transforms)

    def input_files(self) -> list[Path]:
        """The drive folder and the day's calibration files beside it."""
        names = ("calib_cam_to_cam.txt", "calib_velo_to_cam.txt")
        return [
            self.path,
            *(f for folder in (self.path, self.path.parent) for n in names if (f := folder / n).is_file()),
        ]

    def metadata(self) -> dict[str, dict[str, Any]]:
        return {}

    def messages(
        self, topics: Iterable[str] | None = None, *, whole: bool = False
    ) -> Iterator[SessionMessage]:
        """Messages in time order, built from the drive's files as they are read."""
        for entry in self._entries(topics, whole):
            yield SessionMessage(entry.topic, self._msgtype(entry.topic), entry.t, None, self._message(entry))

    def topics(self) -> dict[str, TopicSummary]:
        """Per topic within the span, from the timestamp files (no data read)."""
        summary: dict[str, TopicSummary] = {}
        for entry in self._entries(None, whole=False):
            item = summary.setdefault(
                entry.topic, TopicSummary(self._msgtype(entry.topic), 0, entry.t, entry.t, "KITTI timestamps")
            )
            item.count += 1
            item.last_t = entry.t
        return summary

    def stamps(self, topic: str) -> np.ndarray:
        return np.array([e.t for e in self._entries([topic], whole=False)], dtype=np.int64)

    # -- the toolkit's types, straight from the files ----------------------------------------

    def _scan(self, index: int) -> Scan:
        files, start, end = self._sweeps
        path = files[index]
        raw = np.fromfile(path, dtype="<f4")
        if raw.size % 4:
            raise InputError(
                f"{raw.size * 4} bytes is not a whole number of points (x y z reflectance, float32)",
                path=path,
            )
        cloud = raw.reshape(-1, 4)
        cloud = cloud[np.isfinite(cloud).all(axis=1) & (np.abs(cloud[:, :3]).sum(axis=1) > 0)]
        points = cloud[:, :3].astype(np.float64)
        return Scan(
            points,
            point_times(points, int(start[index]), int(end[index])),
            np.clip(cloud[:, 3] * 255.0, 0, 255).astype(np.float32),
            int(start[index]),
            None,
            POINTS_TOPIC,
        )

    def _imu_sample(self, index: int) -> ImuSample:
        files, stamps = self._oxts  # type: ignore[misc]
        values = np.array(files[index].read_text().split(), dtype=np.float64)
        if values.size != _OXTS_FIELDS:
            raise InputError(
                f"expected {_OXTS_FIELDS} numbers (the OXTS packet), got {values.size}", path=files[index]
            )
        return ImuSample(
            values[_OXTS_ANGULAR_RATE], values[_OXTS_ACCELERATION], int(stamps[index]), None, IMU_TOPIC
        )

    def scans(self, topic: str) -> Iterator[Scan]:
        self._known(topic, POINTS_TOPIC)
        return (self._scan(e.index) for e in self._entries([topic], whole=False))

    def imu(self, topic: str) -> Iterator[ImuSample]:
        self._known(topic, IMU_TOPIC)
        return (self._imu_sample(e.index) for e in self._entries([topic], whole=False))

    def frames(self, topic: str) -> Iterator[Frame]:
        return self.frames_at(topic, None)

    def frames_at(self, topic: str, indices: np.ndarray | None) -> Iterator[Frame]:
        number = self._camera_of(topic)
        wanted = None if indices is None else set(np.asarray(indices).tolist())
        files = self._images[number][0]
        for position, entry in enumerate(self._entries([topic], whole=False)):
            if wanted is None or position in wanted:
                image = read_image(files[entry.index], cv2.IMREAD_UNCHANGED, "this PNG")
                if image.dtype != np.uint8:
                    raise InputError("cannot read this PNG as an 8-bit image", path=files[entry.index])
                yield Frame(image, entry.t, None, topic, "mono8" if image.ndim == 2 else "bgr8")

    def camera_model(self, topic: str) -> CameraModel:
        return self.cameras[self._camera_of(topic)].model

    def _known(self, topic: str, expected: str) -> None:
        if topic != expected:
            raise InputError(
                f"no such topic in a KITTI drive; expected {expected}", path=self.path, field=topic
            )
