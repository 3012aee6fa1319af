"""Holes and fall-through along the seams of a block-trained run (``lts train --blocks``).

The merge could leave a gap where two blocks meet. Two checks look there and only there:

- **Leaned views at the seams**: the keyframes whose camera stands within :data:`SEAM_VIEW_M` of a
  seam, each turned and shifted as :func:`~eval.leaned_views.leaned_poses` does; a pixel is at
  the seam when the ground-truth surface it sees lies within :data:`SEAM_BAND_M` of one (in the
  ground plane). The hole fraction there is reported beside the one of the same views' other
  pixels, so a seam that adds holes stands out from holes the scene has anyway.
- **Physics probes across the seams**: spheres dropped every :data:`SEAM_PROBE_SPACING_M` along
  and across the trajectory's footprint, those within :data:`SEAM_BAND_M` of a seam.

The seams can be another run's (``lts eval RUN --seams BLOCK_RUN/partition.json``): a run trained
in one process scored at the same places says what the seams cost.
"""

from __future__ import annotations

import numpy as np
import trimesh

from eval.leaned_views import ALPHA_SURFACE, MAX_RANGE_M, leaned_poses
from eval.physics import compare_drops, drop_probes, footprint_grid
from rig.mesh_rays import cast_camera_rays, mesh_raycaster, pixel_rays
from slam_bridge.scene import Scene
from splat.blocks.partition import Partition
from splat.model import TriangleModel

#: A surface point or probe within this distance of a seam (m, in the ground plane) is at it.
SEAM_BAND_M = 0.5
#: Views whose camera stands within this distance of a seam look at it.
SEAM_VIEW_M = 2.0
#: At most this many keyframes (evenly spread over those near seams) are leaned at the seams.
MAX_SEAM_KEYFRAMES = 40
#: Probe spacing along and across the footprint near seams (m).
SEAM_PROBE_SPACING_M = 0.1


def seam_holes(
    model: TriangleModel, scene: Scene, reference: trimesh.Trimesh, partition: Partition
) -> dict[str, float | int | None]:
    """``seam_views``, ``seam_hole_fraction`` (holes among the seam pixels) and
    ``off_seam_hole_fraction`` (among the other surface pixels of the same views)."""
    centres = np.stack([k.T_world_cam[:3, 3] for k in scene.keyframes])
    near = np.flatnonzero(partition.seam_distance(partition.frame.project(centres)) <= SEAM_VIEW_M)
    if len(near) > MAX_SEAM_KEYFRAMES:
        near = near[np.linspace(0, len(near) - 1, MAX_SEAM_KEYFRAMES).round().astype(int)]
    poses = leaned_poses(np.stack([scene.keyframes[i].T_world_cam for i in near])) if len(near) else []
    caster, rays = mesh_raycaster(reference), pixel_rays(scene.camera)
    counts = np.zeros((2, 2), dtype=np.int64)  # [seam, off seam] x [surface, holes]
    for pose in poses:
        t_hit = cast_camera_rays(caster, pose, rays)["t_hit"]
        surface = t_hit <= MAX_RANGE_M
        points = pose[:3, 3] + (rays[surface] @ pose[:3, :3].T) * t_hit[surface, None]
        at_seam = np.zeros_like(surface)
        at_seam[surface] = partition.seam_distance(partition.frame.project(points)) <= SEAM_BAND_M
        alpha = model.render_at(scene.camera, pose).alpha.cpu().numpy().reshape(-1)
        hole = surface & (alpha < ALPHA_SURFACE)
        for row, where in enumerate((at_seam, surface & ~at_seam)):
            counts[row] += [int(where.sum()), int((hole & where).sum())]
    fractions = [float(h / s) if s else None for s, h in counts]
    return {
        "seam_views": len(poses),
        "seam_hole_fraction": fractions[0],
        "off_seam_hole_fraction": fractions[1],
    }


def seam_drops(
    collision: trimesh.Trimesh, truth: trimesh.Trimesh, scene: Scene, partition: Partition, up: np.ndarray
) -> dict[str, float | int | None]:
    """``seam_physics_probes`` and ``seam_fall_through_rate``: probes across the seams dropped on
    the collision mesh, over those that rest on the ground truth (needs pybullet)."""
    keyframes = sorted(scene.keyframes, key=lambda k: k.t_ns)
    path = np.stack([k.T_world_cam[:3, 3] for k in keyframes])
    starts = footprint_grid(path, up, spacing_m=SEAM_PROBE_SPACING_M)
    starts = starts[partition.seam_distance(partition.frame.project(starts)) <= SEAM_BAND_M]
    if len(starts) == 0:
        return {"seam_physics_probes": 0, "seam_fall_through_rate": None}
    result = compare_drops(drop_probes(collision, starts, up), drop_probes(truth, starts, up))
    return {"seam_physics_probes": result.probes, "seam_fall_through_rate": result.fall_through_rate}
