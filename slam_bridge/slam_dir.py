"""The SLAM output folder every import and the fallback mapper write: ``mesh.ply`` + ``trajectory.tum``.

``mesh.ply`` is a binary PLY in the world (map) frame; ``trajectory.tum`` holds the LiDAR poses
``T_world_lidar`` in TUM format.
"""

from __future__ import annotations

from pathlib import Path

import trimesh

from rig.errors import InputError
from rig.mesh_io import load_mesh
from rig.trajectory import Trajectory
from rig.trajectory_io import read_tum, write_tum

MESH_FILE = "mesh.ply"
TRAJECTORY_FILE = "trajectory.tum"


def write_slam_dir(out_dir: str | Path, mesh: trimesh.Trimesh, trajectory: Trajectory) -> Path:
    """Write ``out_dir/{mesh.ply, trajectory.tum}``; returns the folder."""
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    mesh.export(out / MESH_FILE, file_type="ply", encoding="binary")
    write_tum(trajectory, out / TRAJECTORY_FILE)
    return out


def load_slam_dir(slam_dir: str | Path) -> tuple[trimesh.Trimesh, Trajectory]:
    """Read a SLAM folder written by :func:`write_slam_dir`."""
    folder = Path(slam_dir)
    if not folder.is_dir():
        raise InputError("no such SLAM folder (expected mesh.ply and trajectory.tum)", path=folder)
    return load_mesh(folder / MESH_FILE), read_tum(folder / TRAJECTORY_FILE)
