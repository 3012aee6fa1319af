"""Split a scene into spatial blocks on the ground plane, each trained on its own and merged after.

A block is an axis-aligned rectangle of the ground plane (its *core*; the outer blocks reach to
infinity so that the cores tile the plane) grown by an overlap margin (its *expanded* region). It
trains on the keyframes that see its core and on the warm-start faces inside its expanded region;
the merge keeps the triangles whose centroid lies in the core. The ground plane is the plane the
cameras' "up" (the mean of their −y axes: cameras of robots and cars are held roughly level) is
normal to; its axes follow the trajectory's main direction.

The plane is split by recursive bisection until every block's training keyframes and warm-start
faces are within their budgets: a block with too many keyframes is halved at the median of its
training cameras across their longer extent, one with too many faces at the median of its face
centroids; a split that leaves a half with all the block's keyframes (every camera sees both
halves) is not made. Blocks are sized by work, not by count, and a scene within the budgets is one
block; blocks that no training camera sees are left out.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from rig.errors import InputError
from rig.transforms import transform_points
from slam_bridge.scene import Keyframe, Scene

#: A keyframe sees a block's core when its camera stands in the expanded region or at least this
#: fraction of its LiDAR returns fall in the core (a long corridor or street is seen from far away:
#: a small fraction would give every block most of the keyframes).
SEES_CORE_FRACTION = 0.25
#: The file in a block run's folder that holds its partition (:meth:`Partition.to_json`).
PARTITION_FILE = "partition.json"
#: Bisection stops at this depth (2^12 blocks) even if a budget is still exceeded.
MAX_DEPTH = 12


@dataclass(frozen=True)
class GroundFrame:
    """World → ground-plane coordinates: ``(P @ axes.T)`` for world points ``P`` ``(N, 3)``.

    Attributes:
        axes: ``(2, 3)`` orthonormal rows spanning the ground plane (the first along the
            trajectory's longer extent).
        up: ``(3,)`` unit normal of the plane.
    """

    axes: np.ndarray
    up: np.ndarray

    def project(self, points: np.ndarray) -> np.ndarray:
        """``(N, 2)`` ground-plane coordinates of world points ``(N, 3)``."""
        return np.asarray(points, dtype=np.float64) @ self.axes.T


@dataclass(frozen=True)
class Block:
    """One block of a :class:`Partition`.

    Attributes:
        index: position in the partition (0-based).
        core: ``(2, 2)`` ground-plane bounds ``[[xmin, ymin], [xmax, ymax]]`` (±inf at the edges).
        margin_m: the expanded region is the core grown by this on every side.
        keyframes: names of the keyframes (training and test) that see the core.
        n_train: how many of them are training keyframes.
        n_faces: warm-start faces with their centroid in the expanded region (the block trains
            them; the face budget bounds those in the core, which halving the core reduces).
    """

    index: int  # the blocks of a partition are numbered 0, 1, ... in this order
    core: np.ndarray
    margin_m: float
    keyframes: tuple[str, ...]
    n_train: int
    n_faces: int

    def in_core(self, xy: np.ndarray, grow_m: float = 0.0) -> np.ndarray:
        """``(N,)`` bool: ground-plane points ``(N, 2)`` inside the core grown by ``grow_m``."""
        return np.all((xy >= self.core[0] - grow_m) & (xy < self.core[1] + grow_m), axis=1)

    def in_expanded(self, xy: np.ndarray) -> np.ndarray:
        """``(N,)`` bool: ground-plane points ``(N, 2)`` inside the expanded region."""
        return self.in_core(xy, self.margin_m)

    def describe(self) -> dict:
        """A JSON-ready summary (core bounds as numbers or null for the open sides)."""
        core = [[None if not np.isfinite(v) else round(float(v), 3) for v in row] for row in self.core]
        return {
            "index": self.index,
            "core": core,
            "margin_m": self.margin_m,
            "keyframes": len(self.keyframes),
            "train_keyframes": self.n_train,
            "faces": self.n_faces,
        }


@dataclass(frozen=True)
class Partition:
    """The blocks of a scene and the ground frame their bounds are in."""

    frame: GroundFrame
    blocks: list[Block]

    def to_json(self) -> dict:
        """What ``RUN_DIR/partition.json`` holds: the frame and every block's :meth:`Block.describe`."""
        return {
            "axes": self.frame.axes.tolist(),
            "up": self.frame.up.tolist(),
            "blocks": [b.describe() for b in self.blocks],
        }

    def seam_distance(self, xy: np.ndarray) -> np.ndarray:
        """``(N,)`` distance (m) of ground-plane points ``(N, 2)`` to the nearest seam: a finite edge
        of the core they lie in (inf outside every core, or in a core without finite edges)."""
        distance = np.full(len(xy), np.inf)
        for block in self.blocks:
            inside = block.in_core(xy)
            gaps = np.concatenate([xy[inside] - block.core[0], block.core[1] - xy[inside]], axis=1)
            distance[inside] = gaps.min(axis=1)  # an open side is an infinite gap
        return distance


def read_partition(path: Path) -> Partition:
    """The partition in ``path`` (a ``partition.json`` written by ``lts train --blocks``); an error
    naming the file when it is not one."""
    from rig.data_file import load_data_file

    data = load_data_file(path, "JSON", "block partition")
    try:
        axes = np.asarray(data["axes"], dtype=np.float64).reshape(2, 3)
        frame = GroundFrame(axes, np.asarray(data["up"], dtype=np.float64).reshape(3))
        blocks = []
        for entry in data["blocks"]:
            low = [-np.inf if v is None else v for v in entry["core"][0]]
            high = [np.inf if v is None else v for v in entry["core"][1]]
            core = np.array([low, high], dtype=np.float64).reshape(2, 2)
            counts = int(entry["train_keyframes"]), int(entry["faces"])
            blocks.append(Block(int(entry["index"]), core, float(entry["margin_m"]), (), *counts))
    except (KeyError, TypeError, ValueError, IndexError) as exc:
        raise InputError(
            f"expected axes, up and blocks with cores ({exc})", path=path, field="blocks"
        ) from None
    return Partition(frame, blocks)


def ground_frame(keyframes: list[Keyframe]) -> GroundFrame:
    """The ground plane of a trajectory: normal to the cameras' mean up (−y) axis, its axes along
    the dominant direction of travel and at right angles to it (buildings and streets run at right
    angles: a corridor with bends gets its cores aligned with its walls), the first the one the
    cameras spread along the most."""
    poses = np.stack([np.asarray(k.T_world_cam, dtype=np.float64) for k in keyframes])
    up = -poses[:, :3, 1].mean(axis=0)
    up /= np.linalg.norm(up)
    seed = np.eye(3)[int(np.argmin(np.abs(up)))]  # any vector not parallel to up starts the basis
    a = np.cross(up, seed)
    a /= np.linalg.norm(a)
    basis = np.stack([a, np.cross(up, a)])
    steps = np.diff(poses[:, :3, 3] @ basis.T, axis=0)
    length = np.linalg.norm(steps, axis=1)
    angle = 0.0
    if length.sum() > 0:
        quadrupled = 4 * np.arctan2(steps[:, 1], steps[:, 0])  # directions 90° apart agree
        mean = (length * np.exp(1j * quadrupled)).sum()
        angle = float(np.angle(mean)) / 4
    c, s = np.cos(angle), np.sin(angle)
    axes = np.array([[c, s], [-s, c]]) @ basis
    spread = np.ptp(poses[:, :3, 3] @ axes.T, axis=0)
    if spread[1] > spread[0]:  # the first axis is the one the cameras spread along the most
        axes = np.stack([axes[1], -axes[0]])
    return GroundFrame(axes, up)


def partition_scene(
    scene: Scene,
    face_centroids: np.ndarray,
    *,
    keyframe_budget: int,
    face_budget: int,
    margin_m: float,
    count: int | None = None,
) -> Partition:
    """Blocks of ``scene`` whose training keyframes and warm-start faces are within the budgets.

    Args:
        scene: the prepared scene (its keyframes' poses and LiDAR returns are read).
        face_centroids: ``(F, 3)`` world centroids of the warm-start mesh's faces.
        keyframe_budget: most training keyframes a block should hold (≥ 1).
        face_budget: most warm-start faces a block's expanded region should hold (≥ 1).
        margin_m: overlap margin around each core (m, ≥ 0).
        count: a number of blocks instead of the budgets: the block with the most training
            keyframes is halved at the median of its cameras until there are ``count`` (fewer when
            no block can be halved any more).

    Raises:
        InputError: a budget below 1 or a negative margin.
    """
    if keyframe_budget < 1 or face_budget < 1:
        raise InputError(f"expected budgets >= 1, got {keyframe_budget} keyframes and {face_budget} faces",
                         field="block budget")  # fmt: skip
    if not margin_m >= 0:
        raise InputError(f"expected a margin >= 0 m, got {margin_m}", field="block margin")
    frame = ground_frame(scene.keyframes)
    sights = [frame.project(_world_lidar(scene, k)) for k in scene.keyframes]
    centres = frame.project(np.stack([k.T_world_cam[:3, 3] for k in scene.keyframes]))
    faces_xy = frame.project(face_centroids)
    is_train = np.array([k.split == "train" for k in scene.keyframes])

    def make(core: np.ndarray) -> Block:
        probe = Block(0, core, margin_m, (), 0, 0)
        sees = np.array([_sees(probe, xy, c) for xy, c in zip(sights, centres, strict=True)], dtype=bool)
        names = tuple(k.name for k, s in zip(scene.keyframes, sees, strict=True) if s)
        return Block(0, core, margin_m, names, int((sees & is_train).sum()),
                     int(probe.in_expanded(faces_xy).sum()))  # fmt: skip

    whole = make(np.array([[-np.inf, -np.inf], [np.inf, np.inf]]))
    leaves: list[Block] = [whole] if count is not None else []
    while count is not None and len(leaves) < count:
        by_size = sorted(leaves, key=lambda b: -b.n_train)
        splits = ((b, _bisect(b.core, centres[is_train], margin_m)) for b in by_size)
        largest, cores = next(((b, c) for b, c in splits if c is not None), (None, None))
        if largest is None:
            break  # no block can be halved any more
        leaves.remove(largest)
        leaves += [make(core) for core in cores]
    pending = [(whole, 0)] if count is None else []
    while pending:
        block, depth = pending.pop()
        cores = None
        if depth < MAX_DEPTH and block.n_train > keyframe_budget:  # split where the cameras stand
            cores = _bisect(block.core, centres[is_train], margin_m)
        elif depth < MAX_DEPTH and int(block.in_core(faces_xy).sum()) > face_budget:  # where the surface is
            cores = _bisect(block.core, faces_xy, margin_m)
        halves = None if cores is None else [make(core) for core in cores]
        if halves is not None and max(half.n_train for half in halves) >= block.n_train:
            halves = None  # every keyframe sees both halves (one room, one wall): splitting gains nothing
        if halves is None:
            leaves.append(block)
        else:
            pending += [(halves[1], depth + 1), (halves[0], depth + 1)]
    blocks = sorted(leaves, key=lambda b: _order_key(b.core, centres))
    trained = [b for b in blocks if b.n_train > 0] or blocks[:1]
    return Partition(frame, [replace(b, index=i) for i, b in enumerate(trained)])


def _world_lidar(scene: Scene, keyframe: Keyframe) -> np.ndarray:
    """``(N, 3)`` the keyframe's LiDAR returns in the world frame."""
    return transform_points(keyframe.T_world_cam, scene.lidar(keyframe).points.astype(np.float64))


def _sees(block: Block, sight_xy: np.ndarray, centre_xy: np.ndarray) -> bool:
    """A keyframe sees ``block``'s core: its camera stands in the expanded region, or enough of its
    returns fall in the core."""
    if block.in_expanded(centre_xy[None])[0]:
        return True
    return len(sight_xy) > 0 and float(block.in_core(sight_xy).mean()) >= SEES_CORE_FRACTION


def _bisect(core: np.ndarray, points: np.ndarray, min_width: float) -> tuple[np.ndarray, np.ndarray] | None:
    """The two halves of ``core`` split at the median of the ground-plane ``points`` ``(N, 2)``
    inside it, across the longer side of their extent (else the other side) where neither half's
    points span less than ``min_width`` (a core narrower than its margin gains nothing from
    splitting: its keyframes are those of the margin); None when no side can be split."""
    inside = points[Block(0, core, 0.0, (), 0, 0).in_core(points)]
    if len(inside) < 2:
        return None
    extent = inside.max(axis=0) - inside.min(axis=0)
    for axis in np.argsort(-extent):
        values = inside[:, axis]
        cut = float(np.median(values))
        if cut - values.min() < min_width or values.max() - cut < min_width:
            continue
        low, high = core.copy(), core.copy()
        low[1, axis] = cut
        high[0, axis] = cut
        return low, high
    return None


def _order_key(core: np.ndarray, centres: np.ndarray) -> float:
    """Blocks are numbered along the trajectory: by the first camera index standing in the core."""
    inside = np.flatnonzero(Block(0, core, 0.0, (), 0, 0).in_core(centres))
    return float(inside[0]) if len(inside) else float("inf")
