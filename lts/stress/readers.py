"""File-reader stress area: a valid sample of each format, truncated, overwritten or given a
NaN, read back by the toolkit's reader. A reader must return finite data or raise an
:class:`~rig.errors.InputError` naming the file: never a library traceback, NaN or a hang."""

from __future__ import annotations

import re
from pathlib import Path
from typing import Any

import numpy as np

from lts.stress.guards import crash_description, time_limit
from lts.stress.samples import READER_KINDS, sample_suffix, write_sample
from rig.calibration import load_calibration
from rig.errors import InputError
from rig.mesh_io import load_mesh
from rig.pointcloud_io import read_point_cloud
from rig.session import SessionReader, recover, session_info
from rig.trajectory_io import read_trajectory

#: How :func:`mutate` damages a file.
MUTATIONS = ("truncate", "flip", "nan")


def mutate(data: bytes, mutation: str, position: float, payload: bytes) -> bytes:
    """``truncate`` at ``position`` (fraction of the length), ``flip``: overwrite bytes there
    with ``payload``, ``nan``: replace the number at or after ``position`` (text) or the float32
    there (binary) with NaN."""
    i = min(int(position * len(data)), max(len(data) - 1, 0))
    if mutation == "truncate":
        return data[:i]
    if mutation == "flip":
        return data[:i] + payload + data[i + len(payload) :]
    if mutation == "nan":
        text = data.decode("latin-1")
        found = re.compile(r"-?\d+\.\d+(e[-+]?\d+)?").search(text, i) or re.compile(r"-?\d+\.\d+").search(
            text
        )
        if found and not text.startswith(("ply\nformat binary", "\x89MCAP")) and "DATA binary" not in text:
            return (text[: found.start()] + "nan" + text[found.end() :]).encode("latin-1")
        j = i - i % 4
        return data[:j] + np.array([np.nan], "<f4").tobytes() + data[j + 4 :]
    raise ValueError(f"unknown mutation {mutation!r}")


def read_back(kind: str, path: Path) -> Any:
    """Read ``path`` with the toolkit's reader for ``kind``; returns what it read."""
    if kind in ("ply_ascii", "ply_binary", "obj"):
        return load_mesh(path)
    if kind.startswith("pcd") or kind == "kitti_bin":
        return read_point_cloud(path)
    if kind in ("tum", "euroc"):
        return read_trajectory(path, kind)
    if kind == "calib_yaml":
        return load_calibration(path)
    if kind == "mcap":
        info = session_info(path)
        messages = sum(1 for _ in SessionReader(path).messages())
        salvage = recover(path, path.with_name(path.stem + "_fixed.mcap"))
        fixed = session_info(path.with_name(path.stem + "_fixed.mcap"))
        return {"info": info, "messages": messages, "salvage": salvage, "fixed": fixed}
    raise ValueError(f"unknown sample kind {kind!r}")


def _nonfinite_leak(kind: str, result: Any) -> str | None:
    """What non-finite or inconsistent data a reader returned, if any."""
    if kind in ("ply_ascii", "ply_binary", "obj"):
        bad = not np.all(np.isfinite(result.vertices))
    elif kind.startswith("pcd") or kind == "kitti_bin":
        bad = not np.all(np.isfinite(result.points))
    elif kind in ("tum", "euroc"):
        bad = not (np.all(np.isfinite(result.translations)) and np.all(np.isfinite(result.quaternions)))
    elif kind == "calib_yaml":
        bad = not (np.all(np.isfinite(result.T_cam_lidar)) and np.all(np.isfinite(result.camera.K)))
    else:
        if result["salvage"]["messages"] != result["info"]["messages"] or result["fixed"]["truncated"]:
            return (
                f"recover salvaged {result['salvage']['messages']} of {result['info']['messages']} messages"
            )
        return None
    return "returned NaN/Inf values" if bad else None


def check_reader(
    kind: str, mutation: str, position: float, payload: bytes, workdir: Path
) -> tuple[list[str], bool]:
    """Mutate a valid ``kind`` file and read it back. Fine: it reads (and returns finite data),
    or raises an :class:`InputError` naming the file. Not fine: another exception (a library
    traceback), an InputError that does not say which file, NaN in the result, or a hang.
    Returns the problems and whether an InputError was raised."""
    source = write_sample(kind, workdir / f"valid{sample_suffix(kind)}")
    path = workdir / f"mutated{sample_suffix(kind)}"
    path.write_bytes(mutate(source.read_bytes(), mutation, position, payload))
    try:
        with time_limit(20.0):
            result = read_back(kind, path)
    except InputError as exc:
        if exc.path is None or Path(exc.path).name != path.name:
            return [f"{kind}/{mutation}: InputError does not name the file: {exc}"], True
        return [], True
    except TimeoutError as exc:
        return [f"{kind}/{mutation}@{position:.3f}: {exc}"], False
    except Exception as exc:
        return [f"{kind}/{mutation}@{position:.3f}: {crash_description(exc)}"], False
    leak = _nonfinite_leak(kind, result)
    return ([f"{kind}/{mutation}@{position:.3f}: {leak}"] if leak else []), False


def stress_reader(rng: np.random.Generator, workdir: Path) -> tuple[list[str], bool]:
    """A random format, mutation, position and payload through :func:`check_reader` (files
    written in ``workdir``): its problems, and whether an InputError was raised."""
    kind = str(rng.choice(READER_KINDS))
    mutation = str(rng.choice(MUTATIONS))
    payload = rng.bytes(int(rng.integers(1, 9)))
    return check_reader(kind, mutation, float(rng.uniform()), payload, workdir)
