"""Point cloud files: PCD (ascii, binary, binary_compressed), KITTI Velodyne ``.bin`` and nuScenes
``.pcd.bin``.

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


def _pcd_header(path: Path) -> tuple[dict[str, list[str]], int]:
    """Header fields (upper-case keys) and the byte offset where the payload starts."""
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
                return header, fh.tell()
        raise InputError("no DATA line in the PCD header", path=path, field="DATA")


_PCD_SIZES = {"F": (4, 8), "I": (1, 2, 4, 8), "U": (1, 2, 4, 8)}


def _header_ints(path: Path, header: dict[str, list[str]], key: str, default: list[str]) -> list[int]:
    try:
        return [int(v) for v in header.get(key, default)]
    except ValueError:
        raise InputError(f"not whole numbers: {header[key]}", path=path, field=key) from None


def _check_layout(path: Path, header: dict[str, list[str]]) -> tuple[int, int]:
    """Validate FIELDS/SIZE/TYPE/COUNT/WIDTH/HEIGHT/POINTS; returns (points, bytes per point).

    Open3D answers a malformed header with a bare RuntimeError (or, for a count that does not
    match the payload, silently pads with zeros or drops points), so it is checked here first.
    """
    fields = header.get("FIELDS", [])
    if not {"x", "y", "z"} <= set(fields):
        raise InputError(f"need x, y, z fields, got {fields}", path=path, field="FIELDS")
    sizes = _header_ints(path, header, "SIZE", [])
    counts = _header_ints(path, header, "COUNT", ["1"] * len(fields))
    types = [t.upper() for t in header.get("TYPE", [])]
    for key, values in (("SIZE", sizes), ("TYPE", types), ("COUNT", counts)):
        if len(values) != len(fields):
            raise InputError(
                f"{len(values)} entries for {len(fields)} fields ({' '.join(fields)})", path=path, field=key
            )
    for name, kind, size, count in zip(fields, types, sizes, counts, strict=True):
        if kind not in _PCD_SIZES:
            raise InputError(
                f"field {name}: unknown type {kind!r}; expected F, I or U", path=path, field="TYPE"
            )
        if size not in _PCD_SIZES[kind]:
            raise InputError(f"field {name}: type {kind} cannot be {size} bytes", path=path, field="SIZE")
        if count < 1:
            raise InputError(f"field {name}: count {count} must be >= 1", path=path, field="COUNT")
    width = _header_ints(path, header, "WIDTH", ["-1"])[0]
    height = _header_ints(path, header, "HEIGHT", ["1"])[0]
    points = _header_ints(path, header, "POINTS", [str(max(width, 0) * height)])[0]
    if points < 0 or width < -1 or height < 0:
        raise InputError(
            f"negative count (WIDTH {width}, HEIGHT {height}, POINTS {points})", path=path, field="POINTS"
        )
    if width >= 0 and width * height != points:
        raise InputError(
            f"WIDTH x HEIGHT = {width} x {height} = {width * height} but POINTS is {points}",
            path=path,
            field="POINTS",
        )
    return points, sum(size * count for size, count in zip(sizes, counts, strict=True))


def _check_payload(path: Path, encoding: str, offset: int, points: int, step: int, values: int) -> None:
    """The payload holds exactly ``points`` records: Open3D pads a short one with zeros, drops
    extra lines and reads words that are not numbers as 0."""
    size = path.stat().st_size - offset
    if encoding == "binary":
        if size < points * step:
            raise InputError(
                f"payload is {size} bytes; {points} points of {step} bytes need {points * step} (truncated?)",
                path=path,
                field="DATA",
            )
    elif encoding == "binary_compressed":
        with path.open("rb") as fh:
            fh.seek(offset)
            head = fh.read(8)
        if len(head) < 8:
            raise InputError("payload ends before its size fields (truncated?)", path=path, field="DATA")
        compressed, uncompressed = (int(v) for v in np.frombuffer(head, dtype="<u4"))
        if compressed > size - 8:
            raise InputError(
                f"compressed payload of {compressed} bytes, only {size - 8} in the file (truncated?)",
                path=path,
                field="DATA",
            )
        if uncompressed != points * step:
            raise InputError(
                f"payload unpacks to {uncompressed} bytes; "
                f"{points} points of {step} bytes need {points * step}",
                path=path,
                field="DATA",
            )
    else:
        with path.open("rb") as fh:
            fh.seek(offset)
            lines = [
                line for line in fh.read().decode("ascii", errors="replace").splitlines() if line.strip()
            ]
        if len(lines) != points:
            raise InputError(
                f"header says {points} points, the file holds {len(lines)} data lines",
                path=path,
                field="POINTS",
            )
        words = " ".join(lines).split()
        try:
            if len(words) != points * values:
                raise ValueError("wrong count")
            np.asarray(words, dtype=np.float64)
        except ValueError:  # find the point to name (slow path, bad files only)
            for i, line in enumerate(lines):
                words = line.split()
                try:
                    if len(words) != values:
                        raise ValueError(f"{len(words)} values; expected {values}")
                    np.asarray(words, dtype=np.float64)
                except ValueError as exc:
                    raise InputError(f"point {i}: {exc}", path=path, field="DATA") from None


def read_pcd(path: str | Path) -> PointCloud:
    """Read a PCD file; raises :class:`InputError` naming the file and header field if malformed.

    Points with a NaN/Inf coordinate (PCD's "no return" in organised clouds) are dropped.
    """
    path = Path(path)
    if not path.is_file():
        raise InputError("file not found", path=path)
    header, offset = _pcd_header(path)
    encoding = header["DATA"][0].lower() if header["DATA"] else ""
    if encoding not in PCD_ENCODINGS:
        raise InputError(f"unknown encoding {encoding!r}; expected {PCD_ENCODINGS}", path=path, field="DATA")
    expected, step = _check_layout(path, header)
    values = sum(_header_ints(path, header, "COUNT", ["1"] * len(header["FIELDS"])))
    _check_payload(path, encoding, offset, expected, step, values)
    if expected == 0:
        return PointCloud(np.zeros((0, 3)), np.zeros(0, np.float32))
    from rig.open3d_lite import o3d

    try:
        # Open3D's own warnings would only repeat, on stdout, what the InputError below says.
        with o3d.utility.VerbosityContextManager(o3d.utility.VerbosityLevel.Error):
            cloud = o3d.t.io.read_point_cloud(str(path), format="pcd")
    except RuntimeError as exc:
        raise InputError(f"cannot decode the {encoding} payload ({exc})", path=path, field="DATA") from None
    if "positions" not in cloud.point:
        raise InputError(f"could not decode the {encoding} payload", path=path, field="DATA")
    points = cloud.point.positions.numpy().astype(np.float64)
    if len(points) != expected:
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


def read_float_records(path: str | Path, fields: int) -> PointCloud:
    """Read a headerless scan of float32 records whose first four fields are ``x y z intensity``:
    KITTI Velodyne ``.bin`` (4 fields) or nuScenes ``.pcd.bin`` (5: ``x y z intensity ring``)."""
    path = Path(path)
    try:
        raw = np.fromfile(path, dtype="<f4")
    except OSError as exc:
        raise InputError(f"cannot read ({exc.strerror})", path=path) from None
    if raw.size % fields:
        raise InputError(
            f"{raw.size * 4} bytes is not a whole number of {4 * fields}-byte records",
            path=path,
            field="data",
        )
    data = raw.reshape(-1, fields)
    # As for PCD: a point with a NaN/Inf coordinate is no return, not a point.
    finite = np.all(np.isfinite(data[:, :3]), axis=1)
    return PointCloud(data[finite, :3].astype(np.float64), data[finite, 3].copy())


def read_kitti_bin(path: str | Path) -> PointCloud:
    """Read a KITTI Velodyne scan: float32 records ``x y z reflectance``."""
    return read_float_records(path, 4)


def read_point_cloud(path: str | Path) -> PointCloud:
    """Read a ``.pcd``, a nuScenes ``.pcd.bin`` or a KITTI ``.bin`` point cloud by file extension."""
    path = Path(path)
    suffix = path.suffix.lower()
    if path.name.lower().endswith(".pcd.bin"):
        return read_float_records(path, 5)
    if suffix == ".pcd":
        return read_pcd(path)
    if suffix == ".bin":
        return read_kitti_bin(path)
    raise InputError(
        f"unknown point cloud format {suffix!r}; expected .pcd, .pcd.bin (nuScenes) or .bin (KITTI)",
        path=path,
    )
