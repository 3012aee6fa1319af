"""Import of PIN-SLAM output (PRBonn/PIN_SLAM): ``mesh/*.ply`` and ``*_poses_tum.txt``.

PIN-SLAM saves meshes during and at the end of a run (``mesh/mesh_frame_<N>.ply``); the one of
the latest frame is the final map. Its poses are LiDAR poses in the first scan's frame, in TUM
format; the loop-closed ``*slam_poses_tum.txt`` is preferred to ``*odom_poses_tum.txt``.
"""

from __future__ import annotations

import re
from pathlib import Path

from rig.errors import InputError
from slam_bridge.generic import import_generic
from slam_bridge.mesh_cleanup import CleanupReport


def _frame_number(path: Path) -> tuple[int, str]:
    numbers = re.findall(r"\d+", path.stem)
    return (int(numbers[-1]) if numbers else -1, path.name)


def find_pin_slam_files(folder: str | Path) -> tuple[Path, Path]:
    """``(final mesh, pose file)`` of a PIN-SLAM output folder."""
    folder = Path(folder)
    meshes = sorted((folder / "mesh").glob("*.ply"), key=_frame_number)
    if not meshes:
        raise InputError("no mesh/*.ply (PIN-SLAM writes meshes with its save_mesh options)", path=folder)
    poses = sorted(folder.glob("*_poses_tum.txt"))
    if not poses:
        raise InputError("no *_poses_tum.txt (PIN-SLAM's TUM pose output)", path=folder)
    preferred = [p for p in poses if "slam" in p.name] or [p for p in poses if "odom" not in p.name] or poses
    return meshes[-1], preferred[0]


def import_pin_slam(folder: str | Path, out_dir: str | Path) -> CleanupReport:
    """Import a PIN-SLAM output folder into ``out_dir/{mesh.ply, trajectory.tum}``."""
    mesh_path, pose_path = find_pin_slam_files(folder)
    return import_generic(mesh_path, pose_path, out_dir, trajectory_format="tum")
