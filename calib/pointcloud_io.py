"""Point cloud files: PCD (ascii, binary, binary_compressed) and KITTI Velodyne ``.bin``.

The PCD header is checked here (so errors name the file and the field); the payload is decoded by
Open3D's tensor reader, which keeps every field and handles all three encodings.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from rig.errors import InputError

PCD_ENCODINGS = ("ascii", "binary", "binary_compressed")
_HEADER_LINES = 16


@dataclass(eq=False)
class PointCloud:
    """Points ``(N, 3)`` float64 in the sensor frame and intensity ``(N,)`` float32 (zeros if absent)."""

    points: np.ndarray
    intensity: np.ndarray

    def __len__(self) -> int:
        return len(self.points)


def _pcd_header(path: Path) -> dict[str, list[str]]:
    header: dict[str, list[str]] = {}
    with path.open("rb") as fh:
        for _ in range(_HEADER_LINES):
            raw = fh.readline()
            if not raw:
                break
            line = raw.decode("ascii", errors="replace").strip()
            if not line or line.startswith("#"):
                continue
            key, *values = line.split()
            header[key.upper()] = values
            if key.upper() == "DATA":
                return header
        raise InputError("no DATA line in the PCD header", path=path, field="DATA")


def read_pcd(path: str | Path) -> PointCloud:
    """Read a PCD file; raises :class:`InputError` naming the file and header field if malformed."""
    path = Path(path)
    if not path.is_file():
        raise InputError("file not found", path=path)
    header = _pcd_header(path)
    fields = header.get("FIELDS", [])
    if not {"x", "y", "z"} <= set(fields):
        raise InputError(f"need x, y, z fields, got {fields}", path=path, field="FIELDS")
    encoding = header["DATA"][0].lower() if header["DATA"] else ""
    if encoding not in PCD_ENCODINGS:
        raise InputError(f"unknown encoding {encoding!r}; expected {PCD_ENCODINGS}", path=path, field="DATA")
    try:
        expected = int(header.get("POINTS", ["-1"])[0])
    except ValueError:
        raise InputError(f"not a count: {header['POINTS']}", path=path, field="POINTS") from None
    import open3d as o3d

    cloud = o3d.t.io.read_point_cloud(str(path), format="pcd")
    if "positions" not in cloud.point:
        if expected == 0:
            return PointCloud(np.zeros((0, 3)), np.zeros(0, np.float32))
        raise InputError(f"could not decode the {encoding} payload", path=path, field="DATA")
    points = cloud.point.positions.numpy().astype(np.float64)
    if expected >= 0 and len(points) != expected:
        raise InputError(
            f"header says {expected} points, payload holds {len(points)}", path=path, field="POINTS"
        )
    intensity = (
        cloud.point.intensity.numpy().reshape(-1).astype(np.float32)
        if "intensity" in cloud.point
        else np.zeros(len(points), np.float32)
    )
    finite = np.all(np.isfinite(points), axis=1)
    return PointCloud(points[finite], intensity[finite])


def read_kitti_bin(path: str | Path) -> PointCloud:
    """Read a KITTI Velodyne scan: float32 records ``x y z reflectance``."""
    path = Path(path)
    try:
        raw = np.fromfile(path, dtype="<f4")
    except OSError as exc:
        raise InputError(f"cannot read ({exc.strerror})", path=path) from None
    if raw.size % 4:
        raise InputError(
            f"{raw.size * 4} bytes is not a whole number of 16-byte records", path=path, field="data"
        )
    data = raw.reshape(-1, 4)
    return PointCloud(data[:, :3].astype(np.float64), data[:, 3].copy())


def read_point_cloud(path: str | Path) -> PointCloud:
    """Read a ``.pcd`` or KITTI ``.bin`` point cloud by file extension."""
    path = Path(path)
    suffix = path.suffix.lower()
    if suffix == ".pcd":
        return read_pcd(path)
    if suffix == ".bin":
        return read_kitti_bin(path)
    raise InputError(f"unknown point cloud format {suffix!r}; expected .pcd or .bin", path=path)
