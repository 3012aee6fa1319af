"""Import of any mapper's output given as a mesh file plus a trajectory file."""

from __future__ import annotations

from pathlib import Path

from rig.errors import InputError
from rig.mesh_io import load_mesh
from rig.trajectory_io import read_trajectory
from slam_bridge.mesh_cleanup import CleanupReport
from slam_bridge.slam_dir import write_slam_dir

MESH_SUFFIXES = (".ply", ".obj", ".glb", ".off", ".stl")
TRAJECTORY_SUFFIXES = (".txt", ".tum", ".csv", ".log")


def files_with_suffix(folder: Path, suffixes: tuple[str, ...]) -> list[Path]:
    """The files in ``folder`` (recursively) with one of ``suffixes`` (any case), sorted."""
    return sorted(p for p in folder.rglob("*") if p.is_file() and p.suffix.lower() in suffixes)


def find_single(folder: Path, suffixes: tuple[str, ...], what: str) -> Path:
    """The one file in ``folder`` (recursively) with one of ``suffixes``, else a clear error."""
    found = files_with_suffix(folder, suffixes)
    if len(found) != 1:
        names = ", ".join(str(p.relative_to(folder)) for p in found[:5]) or "none"
        raise InputError(
            f"expected exactly one {what} file ({'/'.join(suffixes)}), found {len(found)}: {names}; "
            f"pass --{what} to choose",
            path=folder,
        )
    return found[0]


def import_generic(
    mesh_path: str | Path,
    trajectory_path: str | Path,
    out_dir: str | Path,
    trajectory_format: str | None = None,
    times_path: str | Path | None = None,
    rate_hz: float | None = None,
) -> CleanupReport:
    """Import a mesh (PLY/OBJ/...) and a trajectory (TUM/KITTI/EuRoC/4×4) already in one world
    frame, cleaning the mesh as for every import."""
    trajectory = read_trajectory(trajectory_path, trajectory_format, times_path=times_path, rate_hz=rate_hz)
    return write_slam_dir(out_dir, load_mesh(mesh_path), trajectory)[1]
