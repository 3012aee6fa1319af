"""How much of a reconstructed mesh lies where a moving object drove: ghosts of traffic.

A virtual-rig ground truth with moving objects holds each mover's shape (``movers/NAME.ply``, in
its own frame) and its poses at the camera frames (``movers/NAME.tum``). Its *swept volume* is its
shape's bounding box at every one of those poses; nothing static stands there (the street's
vehicles ride 0.3 m above the road), so mesh area inside it is a ghost: returns or pixels of a
vehicle taken for static surface.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import trimesh

from eval.moving_pixels import MOVERS_DIR, mover_names
from rig.mesh_io import load_mesh
from rig.trajectory_io import read_tum
from rig.transforms import transform_points


def inside_swept_volumes(points_gt: np.ndarray, gt_dir: Path) -> np.ndarray:
    """``(N,)`` bool: points ``(N, 3)`` of the ground truth's world that lie inside a mover's
    bounding box at one of its recorded poses (the movers of the ground-truth folder ``gt_dir``)."""
    inside = np.zeros(len(points_gt), dtype=bool)
    for name in mover_names(gt_dir):
        low, high = load_mesh(gt_dir / MOVERS_DIR / f"{name}.ply").bounds
        track = read_tum(gt_dir / MOVERS_DIR / f"{name}.tum")
        poses = track.interpolate(track.t_ns)
        corners = np.array(
            [[x, y, z] for x in (low[0], high[0]) for y in (low[1], high[1]) for z in (low[2], high[2])]
        )
        reach = np.concatenate([transform_points(T, corners) for T in poses])
        near = np.flatnonzero(
            np.all((points_gt >= reach.min(axis=0)) & (points_gt <= reach.max(axis=0)), axis=1) & ~inside
        )
        for T in poses:
            local = (points_gt[near] - T[:3, 3]) @ T[:3, :3]
            inside[near[np.all((local >= low) & (local <= high), axis=1)]] = True
    return inside


def swept_area_fraction(mesh: trimesh.Trimesh, T_gt_world: np.ndarray, gt_dir: Path, samples: int) -> float:
    """Fraction of the area of ``mesh`` (the scene's world frame; ``T_gt_world`` ``(4, 4)`` maps it
    to the ground truth's) inside the movers' swept volumes, from ``samples`` points drawn on it
    in proportion to area (seeded: the same mesh always gives the same number)."""
    points, _ = trimesh.sample.sample_surface(mesh, samples, seed=0)
    return float(inside_swept_volumes(transform_points(T_gt_world, points), gt_dir).mean())
