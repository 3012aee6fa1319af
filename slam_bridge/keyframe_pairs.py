"""Which keyframe pairs to match: those whose cameras see the same surface, judged from the poses
and the SLAM mesh, plus each keyframe's neighbours in time.

Matching every pair grows with the square of the keyframe count; a keyframe here is matched with
at most :data:`MAX_PARTNERS` others, so the pair count grows linearly with the trajectory. A
revisit (loop closure) sees the same surface, so it is found like any other pair.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from rig.camera import CameraModel
from rig.mesh_rays import cast_world_rays, mesh_points

#: Rays cast per keyframe, on an even pixel grid, to find the surface it sees.
SAMPLES_PER_KEYFRAME = 400
#: Partners per keyframe, chosen by co-visibility (neighbours in time come on top).
MAX_PARTNERS = 8
#: Neighbours in time, before and after, matched whatever their co-visibility.
TIME_NEIGHBOURS = 1
#: A pair is co-visible when each keyframe sees at least this fraction of the other's surface samples.
MIN_COVISIBILITY = 0.1
#: Viewing directions further apart than this (degrees) are not matched: SIFT does not hold up to it.
MAX_VIEW_ANGLE_DEG = 60.0
#: Nor keyframes that see the same surface at scales further apart than this factor (distances from
#: the two cameras to the middle of what one of them sees). This keeps the pair choice linear in
#: the trajectory's length at a given keyframe spacing: only keyframes at a comparable distance are
#: looked at closely (the virtual street's 331 keyframes: 13.3 -> 5.8 s, the same 1431 pairs).
MAX_SCALE_CHANGE = 2.0
#: A surface sample counts as seen by another keyframe when that keyframe's ray towards it hits the
#: mesh no nearer than this fraction of its distance (it is not hidden behind another surface).
OCCLUSION_TOLERANCE = 0.05


def surface_samples(raycaster: Any, camera: CameraModel, T_world_cam: np.ndarray) -> np.ndarray:
    """World points ``(S, 3)`` where the keyframe's rays on an even grid of about
    :data:`SAMPLES_PER_KEYFRAME` pixels hit the mesh (rays that miss are left out)."""
    step = max(1.0, np.sqrt(camera.width * camera.height / SAMPLES_PER_KEYFRAME))
    u, v = np.meshgrid(np.arange(step / 2, camera.width, step), np.arange(step / 2, camera.height, step))
    points = mesh_points(raycaster, camera, T_world_cam, np.stack([u.ravel(), v.ravel()], axis=1))
    return points[np.isfinite(points[:, 0])]


def seen_fractions(
    raycaster: Any, camera: CameraModel, poses: np.ndarray, samples: np.ndarray, candidates: np.ndarray
) -> np.ndarray:
    """The fraction ``(N,)`` of world points ``samples`` ``(S, 3)`` that each camera at ``poses``
    ``(N, 4, 4)`` sees: in its image, in front of it and not hidden behind other surfaces of the
    mesh. Only cameras with ``candidates`` ``(N,)`` True are looked at (0 for the others); of
    those, only the ones whose image holds at least :data:`MIN_COVISIBILITY` of the samples cast
    rays (one batch for all of them)."""
    seen = np.zeros(len(poses))
    if len(samples) == 0 or not candidates.any():
        return seen
    index = np.flatnonzero(candidates)
    R, t = poses[index, :3, :3], poses[index, :3, 3]
    local = np.einsum("nji,nsj->nsi", R, samples[None] - t[:, None])  # (n, S, 3) in each camera
    inside = camera.in_image(camera.project(local.reshape(-1, 3))).reshape(len(index), len(samples))
    enough = inside.mean(axis=1) >= MIN_COVISIBILITY
    if not enough.any():
        return seen
    which, sample = np.nonzero(inside[enough])
    distance = np.linalg.norm(local[enough][which, sample], axis=1)
    directions = (samples[sample] - t[enough][which]) / distance[:, None]
    hit = cast_world_rays(raycaster, t[enough][which], directions)["t_hit"]
    visible = hit >= distance * (1 - OCCLUSION_TOLERANCE)
    seen[index[enough]] = np.bincount(which, weights=visible, minlength=int(enough.sum())) / len(samples)
    return seen


def comparable_scales(poses: np.ndarray, samples: list[np.ndarray]) -> np.ndarray:
    """``(N, N)``: True where camera ``j`` at ``poses[j]`` ``(4, 4)`` is within
    :data:`MAX_SCALE_CHANGE` of camera ``i``'s distance to the middle (mean) of its surface samples
    ``samples[i]`` ``(S_i, 3)``; False in rows without samples."""
    centres = poses[:, :3, 3]
    middles = np.stack([s.mean(axis=0) if len(s) else np.full(3, np.nan) for s in samples])
    distance = np.linalg.norm(middles[:, None] - centres[None], axis=2)  # (i, j): camera j to i's middle
    ratio = distance / np.maximum(np.diagonal(distance), 1e-9)[:, None]
    with np.errstate(invalid="ignore"):
        return (ratio <= MAX_SCALE_CHANGE) & (ratio >= 1 / MAX_SCALE_CHANGE)


def covisibility(raycaster: Any, camera: CameraModel, poses: np.ndarray) -> np.ndarray:
    """Symmetric co-visibility ``(N, N)`` of keyframes at ``poses`` ``(N, 4, 4)`` (``T_world_cam``):
    the smaller of the fractions of each one's surface samples the other sees (0 on the diagonal,
    between views more than :data:`MAX_VIEW_ANGLE_DEG` apart and between scales further apart than
    :data:`MAX_SCALE_CHANGE`)."""
    axes = poses[:, :3, 2]
    samples = [surface_samples(raycaster, camera, pose) for pose in poses]
    candidates = (axes @ axes.T >= np.cos(np.radians(MAX_VIEW_ANGLE_DEG))) & comparable_scales(poses, samples)
    np.fill_diagonal(candidates, False)
    seen = np.stack(
        [seen_fractions(raycaster, camera, poses, samples[i], candidates[i]) for i in range(len(poses))]
    )
    return np.minimum(seen, seen.T)


def keyframe_pairs(raycaster: Any, camera: CameraModel, poses: np.ndarray) -> list[tuple[int, int]]:
    """Pairs ``(i, j)``, ``i < j``, of keyframes at ``poses`` ``(N, 4, 4)`` (in time order) to
    match: each keyframe with its :data:`TIME_NEIGHBOURS` neighbours in time and its
    :data:`MAX_PARTNERS` most co-visible others (at least :data:`MIN_COVISIBILITY`)."""
    score = covisibility(raycaster, camera, poses)
    pairs = set()
    for i in range(len(poses)):
        for j in range(i + 1, min(i + 1 + TIME_NEIGHBOURS, len(poses))):
            pairs.add((i, j))
        # Ties broken by time (the stable sort keeps index order), so the pairs are reproducible.
        order = np.argsort(-score[i], kind="stable")[:MAX_PARTNERS]
        pairs.update((min(i, j), max(i, j)) for j in order if score[i, j] >= MIN_COVISIBILITY)
    return sorted(pairs)
