"""Moving objects of a simulated world: rigid vehicles driving along straight lanes.

A :class:`Mover` is a closed mesh in its own frame (x forward, y left, z up, origin on the
ground under its centre) that drives at constant speed along a straight line through the whole
run, so it never stops and becomes part of the static scene. Sensors cast against the movers
posed at the time of each ray (:class:`MovingRaycaster`, in short time slices).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import trimesh

from rig.sim.raycast import Hits, Raycaster

#: Rays are cast against the movers posed at the middle of slices this long (s): a vehicle at
#: 15 m/s is then within 1.9 cm of where it was at the ray's own time.
MOVER_TIME_STEP_S = 0.0025


@dataclass(frozen=True)
class Mover:
    """A rigid object moving at constant velocity.

    Attributes:
        name: a file-safe name (``car_1``).
        mesh: the closed shape in the object's frame (x forward, y left, z up).
        face_material: ``(F,)`` material index of each face.
        start_xy: ``(2,)`` position of the object's origin at time 0 (m).
        velocity_xy: ``(2,)`` velocity (m/s); the object faces along it.
    """

    name: str
    mesh: trimesh.Trimesh
    face_material: np.ndarray
    start_xy: tuple[float, float]
    velocity_xy: tuple[float, float]

    def poses(self, t_s: np.ndarray) -> np.ndarray:
        """``(N, 4, 4)`` object-to-world poses at times ``t_s`` ``(N,)`` (s)."""
        t = np.atleast_1d(np.asarray(t_s, dtype=np.float64))
        vx, vy = self.velocity_xy
        c, s = np.array([vx, vy]) / max(np.hypot(vx, vy), 1e-12)
        T = np.tile(np.eye(4), (len(t), 1, 1))
        T[:, :2, :2] = [[c, -s], [s, c]]
        T[:, 0, 3] = self.start_xy[0] + vx * t
        T[:, 1, 3] = self.start_xy[1] + vy * t
        return T

    def mesh_at(self, t_s: float) -> trimesh.Trimesh:
        """The object's mesh posed in the world at time ``t_s``."""
        return self.mesh.copy().apply_transform(self.poses(np.array([t_s]))[0])


class MovingRaycaster:
    """Ray casting against a static mesh and movers posed at each ray's time.

    Face indices of mover hits continue after the static mesh's faces, mover by mover, in the
    order of ``movers`` (see :func:`mover_face_offsets`).

    Args:
        static: the static scene.
        movers: the moving objects (may be empty).
    """

    def __init__(self, static: trimesh.Trimesh, movers: tuple[Mover, ...]) -> None:
        self.static = Raycaster(static)
        self.movers = movers
        self.n_static_faces = len(static.faces)

    def cast(self, origins: np.ndarray, directions: np.ndarray, t_s: np.ndarray | float = 0.0) -> Hits:
        """Cast rays ``(N, 3)`` from ``origins`` ``(N, 3)`` or ``(3,)`` at times ``t_s`` (scalar
        or ``(N,)``, s); the nearest hit of the static scene or a mover wins."""
        hits = self.static.cast(origins, directions)
        if not self.movers:
            return hits
        directions = np.asarray(directions, dtype=np.float64)
        origins = np.broadcast_to(np.asarray(origins, dtype=np.float64), directions.shape)
        times = np.broadcast_to(np.asarray(t_s, dtype=np.float64), len(directions))
        slot = np.floor(times / MOVER_TIME_STEP_S)
        for s in np.unique(slot):
            rows = np.flatnonzero(slot == s)
            posed = trimesh.util.concatenate([m.mesh_at((s + 0.5) * MOVER_TIME_STEP_S) for m in self.movers])
            moving = Raycaster(posed).cast(origins[rows], directions[rows])
            nearer = moving.distance < hits.distance[rows]
            if nearer.any():
                r = rows[nearer]
                hits.distance[r] = moving.distance[nearer]
                hits.face[r] = moving.face[nearer] + self.n_static_faces
                hits.bary[r] = moving.bary[nearer]
                hits.normal[r] = moving.normal[nearer]
                hits.points[r] = moving.points[nearer]
        return hits


def mover_face_offsets(n_static_faces: int, movers: tuple[Mover, ...]) -> np.ndarray:
    """``(M + 1,)`` first face index of each mover among all faces, and the total count."""
    return n_static_faces + np.concatenate([[0], np.cumsum([len(m.mesh.faces) for m in movers])]).astype(
        np.int64
    )


def mover_of_face(face: np.ndarray, n_static_faces: int, movers: tuple[Mover, ...]) -> np.ndarray:
    """``(N,)`` index of the mover each face index ``(N,)`` belongs to; -1 for static faces."""
    offsets = mover_face_offsets(n_static_faces, movers)
    return np.where(face >= n_static_faces, np.searchsorted(offsets, face, side="right") - 1, -1)


def inside_movers(
    points: np.ndarray, movers: tuple[Mover, ...], t_s: np.ndarray | float, margin_m: float = 0.0
) -> np.ndarray:
    """``(N,)`` bool: points ``(N, 3)`` (world) lie inside a mover's bounding box (grown by
    ``margin_m``) at any of the times ``t_s`` (scalar or ``(K,)``): the movers' swept volumes.

    A mover keeps its heading, so in its frame at time 0 a point moves back along x by the
    distance travelled: one sorted search over the times per point, exact for every time given.
    """
    points = np.asarray(points, dtype=np.float64)
    inside = np.zeros(len(points), dtype=bool)
    for mover in movers:
        T0 = mover.poses(np.zeros(1))[0]
        local = (points - T0[:3, 3]) @ T0[:3, :3]
        low, high = mover.mesh.bounds[0] - margin_m, mover.mesh.bounds[1] + margin_m
        across = np.all((local[:, 1:] >= low[1:]) & (local[:, 1:] <= high[1:]), axis=1)
        travel = np.sort(np.hypot(*mover.velocity_xy) * np.atleast_1d(np.asarray(t_s, dtype=np.float64)))
        # Inside at some time: a travel distance within [x - high_x, x - low_x].
        first = np.searchsorted(travel, local[:, 0] - high[0], side="left")
        reached = first < len(travel)
        reached[reached] = travel[first[reached]] <= local[reached, 0] - low[0]
        inside |= across & reached
    return inside
