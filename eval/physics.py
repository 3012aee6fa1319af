"""Physics collision test: drop probes on a mesh in pybullet and compare with ground truth.

The exported collision mesh is loaded as a static concave triangle mesh; small spheres are
dropped on a grid along the trajectory's ground footprint. Where the reconstruction has a hole a
probe falls through; where its surface is off, probes rest at the wrong height.
"""

from __future__ import annotations

import tempfile
from dataclasses import asdict, dataclass
from pathlib import Path

import numpy as np
import trimesh

from rig.errors import InputError

PROBE_RADIUS_M = 0.04
_SIM_HZ = 240
_SETTLE_S = 1.5
_MESH_GROUP, _PROBE_GROUP = 1, 2
#: pybullet refuses meshes with more vertices than this when they are passed in memory
#: (B3_MAX_NUM_VERTICES of its shared-memory command).
_MAX_IN_MEMORY_VERTICES = 131_072


@dataclass(frozen=True)
class DropResult:
    """Where each probe came to rest.

    Attributes:
        start: ``(P, 3)`` drop positions.
        rest_height: ``(P,)`` final height of each probe's centre along ``up`` (m).
        fell_through: ``(P,)`` True where a probe ended below the mesh's lowest point.
    """

    start: np.ndarray
    rest_height: np.ndarray
    fell_through: np.ndarray


@dataclass(frozen=True)
class CollisionComparison:
    """Reconstruction vs ground truth over probes that rest on the ground truth."""

    probes: int
    fall_through_rate: float
    mean_height_error_m: float
    max_height_error_m: float

    def to_dict(self) -> dict[str, float | int]:
        return asdict(self)


def footprint_grid(
    positions: np.ndarray,
    up: np.ndarray,
    spacing_m: float = 0.5,
    half_width_m: float = 0.5,
    clearance_m: float = 0.2,
) -> np.ndarray:
    """Drop points ``(P, 3)`` on a grid around a trajectory's positions ``(N, 3)``.

    Points lie every ``spacing_m`` along the path and at ``±half_width_m`` across it, lowered by
    ``clearance_m`` below the trajectory (a camera height above the floor) so that they start
    under any ceiling.
    """
    up = np.asarray(up, dtype=np.float64) / np.linalg.norm(up)
    positions = np.asarray(positions, dtype=np.float64)
    if len(positions) < 2:
        raise InputError("need at least 2 trajectory positions for a footprint", field="trajectory")
    steps = np.linalg.norm(np.diff(positions, axis=0), axis=1)
    arc = np.concatenate([[0.0], np.cumsum(steps)])
    stations = np.arange(0.0, arc[-1] + 1e-9, spacing_m)
    centre = np.stack([np.interp(stations, arc, positions[:, k]) for k in range(3)], axis=1)
    heading = np.gradient(centre, axis=0) if len(centre) > 1 else np.array([[1.0, 0.0, 0.0]])
    heading -= (heading @ up)[:, None] * up
    side = np.cross(up, heading)
    norms = np.linalg.norm(side, axis=1, keepdims=True)
    side = np.divide(side, norms, out=np.zeros_like(side), where=norms > 1e-9)
    offsets = np.arange(-half_width_m, half_width_m + 1e-9, spacing_m)
    grid = centre[:, None, :] + offsets[None, :, None] * side[:, None, :] - clearance_m * up
    return grid.reshape(-1, 3)


def _static_mesh_shape(pb, mesh: trimesh.Trimesh, client: int) -> int:
    """A concave triangle-mesh collision shape of ``mesh``: passed in memory, or, beyond what
    pybullet takes in memory (:data:`_MAX_IN_MEMORY_VERTICES`), through a temporary OBJ file."""
    if len(mesh.vertices) <= _MAX_IN_MEMORY_VERTICES:
        return pb.createCollisionShape(
            pb.GEOM_MESH,
            vertices=np.asarray(mesh.vertices, dtype=np.float64).tolist(),
            indices=np.asarray(mesh.faces, dtype=np.int64).reshape(-1).tolist(),
            flags=pb.GEOM_FORCE_CONCAVE_TRIMESH,
            physicsClientId=client,
        )
    with tempfile.TemporaryDirectory(prefix="lts-physics-") as folder:
        path = Path(folder) / "mesh.obj"
        trimesh.Trimesh(mesh.vertices, mesh.faces, process=False).export(path)
        try:
            return pb.createCollisionShape(
                pb.GEOM_MESH, fileName=str(path), flags=pb.GEOM_FORCE_CONCAVE_TRIMESH, physicsClientId=client
            )
        except pb.error as exc:
            raise InputError(f"pybullet cannot load a {len(mesh.faces)}-face mesh ({exc})") from None


def drop_probes(
    mesh: trimesh.Trimesh,
    starts: np.ndarray,
    up: np.ndarray = (0.0, 0.0, 1.0),
    radius_m: float = PROBE_RADIUS_M,
) -> DropResult:
    """Drop spheres from ``starts`` ``(P, 3)`` onto ``mesh`` (static, concave) and let them settle.

    Probes collide with the mesh only, not with each other.
    """
    import pybullet as pb

    up = np.asarray(up, dtype=np.float64) / np.linalg.norm(up)
    starts = np.asarray(starts, dtype=np.float64)
    client = pb.connect(pb.DIRECT)
    try:
        pb.setGravity(*(-9.81 * up), physicsClientId=client)
        pb.setTimeStep(1.0 / _SIM_HZ, physicsClientId=client)
        shape = _static_mesh_shape(pb, mesh, client)
        ground = pb.createMultiBody(baseMass=0, baseCollisionShapeIndex=shape, physicsClientId=client)
        pb.setCollisionFilterGroupMask(ground, -1, _MESH_GROUP, _PROBE_GROUP, physicsClientId=client)
        sphere = pb.createCollisionShape(pb.GEOM_SPHERE, radius=radius_m, physicsClientId=client)
        probes = []
        for start in starts:
            body = pb.createMultiBody(
                baseMass=0.1,
                baseCollisionShapeIndex=sphere,
                basePosition=start.tolist(),
                physicsClientId=client,
            )
            pb.changeDynamics(body, -1, lateralFriction=1.0, rollingFriction=0.05, physicsClientId=client)
            pb.setCollisionFilterGroupMask(body, -1, _PROBE_GROUP, _MESH_GROUP, physicsClientId=client)
            probes.append(body)
        for _ in range(int(_SETTLE_S * _SIM_HZ)):
            pb.stepSimulation(physicsClientId=client)
        final = np.array([pb.getBasePositionAndOrientation(b, physicsClientId=client)[0] for b in probes])
    finally:
        pb.disconnect(client)
    heights = final.reshape(-1, 3) @ up
    lowest = float(np.min(np.asarray(mesh.vertices) @ up))
    return DropResult(starts, heights, heights < lowest - radius_m)


def compare_drops(reconstructed: DropResult, ground_truth: DropResult) -> CollisionComparison:
    """Fall-through rate and resting-height error of the reconstruction, over the probes that
    rest on the ground truth (probes from the same starts)."""
    if reconstructed.start.shape != ground_truth.start.shape or not np.allclose(
        reconstructed.start, ground_truth.start
    ):
        raise ValueError("the two drops must start from the same probe positions")
    valid = ~ground_truth.fell_through
    if not valid.any():
        raise InputError("no probe rests on the ground-truth mesh: wrong up axis or footprint?", field="up")
    fell = reconstructed.fell_through[valid]
    rested = valid & ~reconstructed.fell_through
    errors = np.abs(reconstructed.rest_height[rested] - ground_truth.rest_height[rested])
    return CollisionComparison(
        probes=int(valid.sum()),
        fall_through_rate=float(fell.mean()),
        mean_height_error_m=float(errors.mean()) if errors.size else float("nan"),
        max_height_error_m=float(errors.max()) if errors.size else float("nan"),
    )
