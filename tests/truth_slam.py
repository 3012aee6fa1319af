"""A SLAM folder made of a virtual-rig ground truth, for tests that need mapping without its noise."""

from __future__ import annotations

import shutil
from pathlib import Path


def write_truth_slam(sim_dir: Path, out: Path) -> Path:
    """``out`` holding ``sim_dir``'s true mesh and true LiDAR trajectory as a SLAM folder."""
    out.mkdir(parents=True, exist_ok=True)
    shutil.copyfile(sim_dir / "ground_truth" / "mesh.ply", out / "mesh.ply")
    shutil.copyfile(sim_dir / "ground_truth" / "trajectory_lidar.tum", out / "trajectory.tum")
    return out
