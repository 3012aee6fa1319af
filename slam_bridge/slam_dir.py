"""The SLAM output folder every import and the fallback mapper write: ``mesh.ply`` + ``trajectory.tum``.

``mesh.ply`` is a binary PLY in the world (map) frame, cleaned (:func:`clean_mesh`);
``trajectory.tum`` holds the LiDAR poses ``T_world_lidar`` in TUM format.
"""

from __future__ import annotations

from pathlib import Path

import trimesh

from rig.errors import InputError
from rig.mesh_io import load_mesh
from rig.trajectory import Trajectory
from rig.trajectory_io import read_tum, write_tum
from slam_bridge.mesh_cleanup import CleanupReport, clean_mesh

MESH_FILE = "mesh.ply"
TRAJECTORY_FILE = "trajectory.tum"


def write_slam_dir(
    out_dir: str | Path, mesh: trimesh.Trimesh, trajectory: Trajectory
) -> tuple[trimesh.Trimesh, CleanupReport]:
    """Clean a mapper's ``mesh`` (world frame; :func:`clean_mesh`, the trajectory's positions as
    viewpoints) and write it with ``trajectory`` as ``out_dir/{mesh.ply, trajectory.tum}``.
    Returns the cleaned mesh and what the cleanup did."""
    cleaned, report = clean_mesh(mesh.vertices, mesh.faces, viewpoints=trajectory.translations)
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    cleaned.export(out / MESH_FILE, file_type="ply", encoding="binary")
    write_tum(trajectory, out / TRAJECTORY_FILE)
    return cleaned, report


def load_slam_dir(slam_dir: str | Path) -> tuple[trimesh.Trimesh, Trajectory]:
    """Read a SLAM folder written by :func:`write_slam_dir`."""
    folder = Path(slam_dir)
    if not folder.is_dir():
        raise InputError("no such SLAM folder (expected mesh.ply and trajectory.tum)", path=folder)
    return load_mesh(folder / MESH_FILE), read_tum(folder / TRAJECTORY_FILE)
