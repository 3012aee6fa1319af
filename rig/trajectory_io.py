"""Trajectory files: TUM, KITTI (3×4 poses + separate times), EuRoC csv and 4×4-per-line.

Readers keep every number exactly (times as integer nanoseconds parsed from the decimal text,
values as float64) and writers print floats with ``repr``, so parse → write → parse is exact.
Malformed input raises :class:`~rig.errors.InputError` naming the file and line.
"""

from __future__ import annotations

import logging
import re
from collections.abc import Callable, Iterator, Sequence
from decimal import Decimal, InvalidOperation
from pathlib import Path

import numpy as np

from rig.errors import InputError
from rig.trajectory import Trajectory

FORMATS = ("tum", "kitti", "euroc", "matrix")
TUM_FIELDS = ("t", "tx", "ty", "tz", "qx", "qy", "qz", "qw")
KITTI_FIELDS = tuple(f"r{r}{c}" for r in range(3) for c in range(4))
EUROC_FIELDS = ("timestamp_ns", "px", "py", "pz", "qw", "qx", "qy", "qz")
MATRIX_FIELDS = tuple(f"m{r}{c}" for r in range(4) for c in range(4))
_NS_PER_S = 1_000_000_000
_INT64_MIN, _INT64_MAX = int(np.iinfo(np.int64).min), int(np.iinfo(np.int64).max)
logger = logging.getLogger(__name__)


def seconds_text_to_ns(text: str) -> int:
    """Exact integer nanoseconds of a decimal seconds string such as ``"1305031102.1758"``.

    Raises:
        ValueError: the text is not a finite number.
    """
    try:
        value = Decimal(text)
    except InvalidOperation:
        raise ValueError(f"{text!r} is not a number") from None
    if not value.is_finite():
        raise ValueError(f"{text!r} is not a finite number")
    t_ns = int((value * _NS_PER_S).to_integral_value())
    if not _INT64_MIN <= t_ns <= _INT64_MAX:
        raise ValueError(f"{text!r} s is outside the range of int64 nanoseconds (about ±292 years)")
    return t_ns


def ns_to_seconds_text(t_ns: int) -> str:
    """Decimal seconds text with 9 decimals, exact for integer nanoseconds."""
    sign = "-" if t_ns < 0 else ""
    whole, frac = divmod(abs(int(t_ns)), _NS_PER_S)
    return f"{sign}{whole}.{frac:09d}"


def _data_lines(path: Path, separator: str | None) -> Iterator[tuple[int, list[str]]]:
    """Yield (line number, fields) of non-empty, non-comment lines."""
    try:
        text = path.read_text()
    except OSError as exc:
        raise InputError(f"cannot read trajectory ({exc.strerror})", path=path) from None
    except UnicodeDecodeError:
        raise InputError("not a text file", path=path) from None
    for number, raw in enumerate(text.splitlines(), start=1):
        line = raw.strip()
        if not line or line.startswith("#"):
            continue
        yield number, [f.strip() for f in line.split(separator)]


def _parse_rows(
    path: Path, names: Sequence[str], separator: str | None = None
) -> tuple[list[str], np.ndarray, list[int]]:
    """Parse a table of numbers; returns first-column texts, the float array and line numbers."""
    first: list[str] = []
    rows: list[list[float]] = []
    line_numbers: list[int] = []
    for number, fields in _data_lines(path, separator):
        if len(fields) < len(names):
            raise InputError(
                f"expected {len(names)} numbers ({' '.join(names)}), got {len(fields)}",
                path=path,
                line=number,
            )
        values = []
        for name, text in zip(names, fields, strict=False):
            try:
                value = float(text)
            except ValueError:
                raise InputError(f"{text!r} is not a number", path=path, line=number, field=name) from None
            if not np.isfinite(value):
                raise InputError(f"{text!r} is not finite", path=path, line=number, field=name)
            values.append(value)
        first.append(fields[0])
        rows.append(values)
        line_numbers.append(number)
    if not rows:
        raise InputError("no poses in file", path=path)
    return first, np.asarray(rows, dtype=np.float64), line_numbers


def _times_from_text(path: Path, texts: list[str], line_numbers: list[int], field: str) -> np.ndarray:
    t_ns = np.empty(len(texts), dtype=np.int64)
    for i, (text, line) in enumerate(zip(texts, line_numbers, strict=True)):
        try:
            t_ns[i] = seconds_text_to_ns(text)
        except ValueError as exc:
            raise InputError(str(exc), path=path, line=line, field=field) from None
    return t_ns


def _build(path: Path, build: Callable[[], Trajectory], line_numbers: list[int]) -> Trajectory:
    """Run a Trajectory constructor, turning a pose index in its error into a line number, and
    warn about repeated stamps (kept, see :class:`Trajectory`)."""
    try:
        trajectory = build()
    except InputError as exc:
        match = re.search(r"pose (\d+)", exc.reason)
        line = line_numbers[int(match.group(1))] if match else None
        raise InputError(exc.reason, path=path, field=exc.field, line=line) from None
    repeated = np.flatnonzero(np.diff(trajectory.t_ns) == 0)
    if repeated.size:
        logger.warning(
            "%s:%d: %d repeated timestamp(s), first %s s; kept (interpolation uses the last pose of a stamp)",
            path,
            line_numbers[int(repeated[0]) + 1],
            repeated.size,
            ns_to_seconds_text(int(trajectory.t_ns[repeated[0]])),
        )
    return trajectory


def read_tum(path: str | Path) -> Trajectory:
    """Read a TUM file: ``t tx ty tz qx qy qz qw`` per line (t in seconds)."""
    path = Path(path)
    texts, rows, lines = _parse_rows(path, TUM_FIELDS)
    t_ns = _times_from_text(path, texts, lines, "t")
    return _build(
        path,
        lambda: Trajectory.from_quaternions(t_ns, rows[:, 1:4], rows[:, 4:8], source=str(path)),
        lines,
    )


def write_tum(trajectory: Trajectory, path: str | Path) -> None:
    """Write a TUM file (``# timestamp tx ty tz qx qy qz qw`` header)."""
    lines = ["# timestamp tx ty tz qx qy qz qw"]
    for t, p, q in zip(trajectory.t_ns, trajectory.translations, trajectory.quaternions, strict=True):
        lines.append(" ".join([ns_to_seconds_text(int(t)), *map(repr, p.tolist()), *map(repr, q.tolist())]))
    Path(path).write_text("\n".join(lines) + "\n")


def _read_times_file(path: Path) -> np.ndarray:
    texts, _, lines = _parse_rows(path, ("t",))
    return _times_from_text(path, texts, lines, "t")


def _times_for(path: Path, count: int, times_path: str | Path | None, rate_hz: float | None) -> np.ndarray:
    """Times for a format without stamps: from a times file, else ``count`` samples at ``rate_hz``."""
    if times_path is not None:
        t_ns = _read_times_file(Path(times_path))
        if len(t_ns) != count:
            raise InputError(
                f"{len(t_ns)} times for {count} poses in {path}; expected one time per pose",
                path=times_path,
            )
        return t_ns
    if rate_hz is None:
        raise InputError("poses carry no times: give a times file or a positive rate", path=path)
    if not (np.isfinite(rate_hz) and rate_hz > 0):
        raise InputError(f"rate must be a positive number of Hz, got {rate_hz}", path=path, field="rate")
    step_ns = _NS_PER_S / rate_hz
    if step_ns < 1 or (count - 1) * step_ns > _INT64_MAX:
        raise InputError(
            f"{count} poses at {rate_hz:g} Hz do not fit integer nanoseconds", path=path, field="rate"
        )
    return np.round(np.arange(count) * step_ns).astype(np.int64)


def read_kitti(
    path: str | Path, times_path: str | Path | None = None, *, rate_hz: float | None = None
) -> Trajectory:
    """Read KITTI poses (12 numbers per line, row-major 3×4) with times from ``times_path``
    (one time in seconds per line) or, without it, at a constant ``rate_hz``."""
    path = Path(path)
    _, rows, lines = _parse_rows(path, KITTI_FIELDS)
    t_ns = _times_for(path, len(rows), times_path, rate_hz)
    poses = rows[:, :12].reshape(-1, 3, 4)
    return _build(path, lambda: Trajectory.from_poses(t_ns, poses, source=str(path)), lines)


def write_kitti(trajectory: Trajectory, path: str | Path, times_path: str | Path | None = None) -> None:
    """Write KITTI poses (and, if ``times_path`` is given, the times file beside them)."""
    poses = trajectory.poses[:, :3, :].reshape(-1, 12)
    Path(path).write_text("".join(" ".join(map(repr, row.tolist())) + "\n" for row in poses))
    if times_path is not None:
        Path(times_path).write_text("".join(ns_to_seconds_text(int(t)) + "\n" for t in trajectory.t_ns))


def read_euroc(path: str | Path) -> Trajectory:
    """Read a EuRoC ground-truth csv: ``timestamp_ns, px, py, pz, qw, qx, qy, qz, ...``."""
    path = Path(path)
    texts, rows, lines = _parse_rows(path, EUROC_FIELDS, separator=",")
    t_ns = np.empty(len(texts), dtype=np.int64)
    for i, text in enumerate(texts):
        try:
            value = int(text)
        except ValueError:
            raise InputError(
                f"{text!r} is not integer nanoseconds", path=path, line=lines[i], field="timestamp_ns"
            ) from None
        if not _INT64_MIN <= value <= _INT64_MAX:
            raise InputError(
                f"{text!r} is outside the range of int64 nanoseconds",
                path=path,
                line=lines[i],
                field="timestamp_ns",
            )
        t_ns[i] = value
    quats_xyzw = rows[:, [5, 6, 7, 4]]
    return _build(
        path,
        lambda: Trajectory.from_quaternions(t_ns, rows[:, 1:4], quats_xyzw, source=str(path)),
        lines,
    )


def write_euroc(trajectory: Trajectory, path: str | Path) -> None:
    """Write a EuRoC-style csv with position and orientation columns."""
    lines = [
        "#timestamp, p_RS_R_x [m], p_RS_R_y [m], p_RS_R_z [m], q_RS_w [], q_RS_x [], q_RS_y [], q_RS_z []"
    ]
    for t, p, q in zip(trajectory.t_ns, trajectory.translations, trajectory.quaternions, strict=True):
        x, y, z, w = q.tolist()
        lines.append(",".join([str(int(t)), *map(repr, p.tolist()), repr(w), repr(x), repr(y), repr(z)]))
    Path(path).write_text("\n".join(lines) + "\n")


def read_matrix_lines(
    path: str | Path, times_path: str | Path | None = None, *, rate_hz: float | None = None
) -> Trajectory:
    """Read one row-major 4×4 camera-to-world matrix per line (NICE-SLAM Replica ``traj.txt``)."""
    path = Path(path)
    _, rows, lines = _parse_rows(path, MATRIX_FIELDS)
    t_ns = _times_for(path, len(rows), times_path, rate_hz)
    return _build(
        path,
        lambda: Trajectory.from_poses(t_ns, rows[:, :16].reshape(-1, 4, 4), source=str(path)),
        lines,
    )


def write_matrix_lines(trajectory: Trajectory, path: str | Path) -> None:
    """Write one row-major 4×4 matrix per line (times are not stored in this format)."""
    rows = trajectory.poses.reshape(-1, 16)
    Path(path).write_text("".join(" ".join(map(repr, row.tolist())) + "\n" for row in rows))


def detect_format(path: str | Path) -> str:
    """Guess the format of a trajectory file from its first data line.

    Raises:
        InputError: the layout matches none of :data:`FORMATS`.
    """
    path = Path(path)
    for number, fields in _data_lines(path, None):
        if "," in fields[0]:  # a csv line, with or without spaces after the commas
            return "euroc"
        counts = {8: "tum", 12: "kitti", 16: "matrix"}
        if len(fields) in counts:
            return counts[len(fields)]
        raise InputError(
            f"cannot tell the trajectory format from {len(fields)} fields; expected 8 (TUM), "
            "12 (KITTI), 16 (4x4 matrix) or a EuRoC csv",
            path=path,
            line=number,
        )
    raise InputError("no poses in file", path=path)


def read_trajectory(
    path: str | Path,
    fmt: str | None = None,
    *,
    times_path: str | Path | None = None,
    rate_hz: float | None = None,
) -> Trajectory:
    """Read a trajectory in ``fmt`` (one of :data:`FORMATS`; detected when None)."""
    fmt = fmt or detect_format(path)
    if fmt == "tum":
        return read_tum(path)
    if fmt == "euroc":
        return read_euroc(path)
    if fmt == "kitti":
        return read_kitti(path, times_path, rate_hz=rate_hz)
    if fmt == "matrix":
        return read_matrix_lines(path, times_path, rate_hz=rate_hz)
    raise InputError(f"unknown trajectory format {fmt!r}; expected one of {', '.join(FORMATS)}", path=path)


def write_trajectory(trajectory: Trajectory, path: str | Path, fmt: str = "tum") -> None:
    """Write ``trajectory`` in ``fmt`` (KITTI writes its times to ``<stem>_times.txt`` beside it)."""
    path = Path(path)
    if fmt == "tum":
        write_tum(trajectory, path)
    elif fmt == "euroc":
        write_euroc(trajectory, path)
    elif fmt == "kitti":
        write_kitti(trajectory, path, path.with_name(f"{path.stem}_times.txt"))
    elif fmt == "matrix":
        write_matrix_lines(trajectory, path)
    else:
        raise InputError(
            f"unknown trajectory format {fmt!r}; expected one of {', '.join(FORMATS)}", path=path
        )
