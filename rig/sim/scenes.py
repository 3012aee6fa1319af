"""Procedural scene presets: triangle meshes with a material per face, a robot path and a rig.

World frame: z up, metres. Solids (boxes, table parts, steps) are closed meshes; rooms and
corridors are closed shells whose faces point inwards.
"""

from __future__ import annotations

import itertools
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np
import trimesh
from scipy.spatial.transform import Rotation

from rig.errors import InputError
from rig.sim.board import BoardSpec, board_mesh
from rig.sim.movers import Mover
from rig.sim.office import OFFICE_PATH, office
from rig.sim.shapes import SceneMesh, box, join_parts, shell
from rig.sim.street import EGO_LANE_Y, EGO_SPEED_MPS, street, street_traffic
from rig.sim.textures import MATERIAL_IDS
from rig.transforms import make_transform

#: Rotation from a LiDAR frame (x forward, y left, z up) to the OpenCV camera frame.
R_CAM_LIDAR_NOMINAL = np.array([[0.0, -1.0, 0.0], [0.0, 0.0, -1.0], [1.0, 0.0, 0.0]])


def table(centre_xy: tuple[float, float], rng: np.random.Generator) -> list[SceneMesh]:
    """A wooden table top on four thin (4 cm) metal legs."""
    w, d, h, top, leg = 1.2, 0.8, 0.74, 0.04, 0.04
    x, y = centre_xy
    yaw = rng.uniform(-0.2, 0.2)
    R = Rotation.from_euler("z", yaw).as_matrix()[:2, :2]
    parts = [box((w, d, top), (x, y, h - top / 2), "wood", yaw)]
    for sx in (-1, 1):
        for sy in (-1, 1):
            lx, ly = R @ np.array([sx * (w / 2 - 0.06), sy * (d / 2 - 0.06)])
            parts.append(box((leg, leg, h - top), (x + lx, y + ly, (h - top) / 2), "metal", yaw))
    return parts


def room(rng: np.random.Generator) -> SceneMesh:
    """An 8 × 6 × 2.6 m room: boxes, a table on thin legs, and a 15 cm step up to a platform."""
    walls = shell((8.0, 6.0, 2.6), "plaster")
    walls.face_material[walls.mesh.face_normals[:, 1] > 0.5] = MATERIAL_IDS["bricks"]  # the wall at y = 0
    parts = [walls]
    for size, centre, material in (
        ((0.8, 0.6, 0.6), (0.6, 5.2), "cardboard"),
        ((0.5, 0.5, 0.9), (7.3, 0.6), "fabric"),
        ((0.6, 1.2, 0.45), (0.5, 3.0), "fabric"),
        ((1.0, 0.4, 1.6), (4.8, 5.55), "wood"),
        ((0.45, 0.45, 0.45), (2.4, 5.5), "cardboard"),
    ):
        jitter = rng.uniform(-0.1, 0.1, 2)
        parts.append(
            box(
                size,
                (centre[0] + jitter[0], centre[1] + jitter[1], size[2] / 2),
                material,
                rng.uniform(-0.15, 0.15),
            )
        )
    parts += table((3.0, 4.4), rng)
    parts.append(box((1.8, 1.8, 0.15), (7.1, 5.1, 0.075), "concrete"))  # the step
    return join_parts(parts)


def _quads(quads: list[tuple[int, int, int, int]]) -> np.ndarray:
    """Triangles ``(2Q, 3)`` of counter-clockwise quads (as seen from the side they face)."""
    q = np.asarray(quads)
    return np.concatenate([q[:, [0, 1, 2]], q[:, [0, 2, 3]]])


def tunnel(centreline: np.ndarray, width: float, height: float, walls: str, floor: str) -> SceneMesh:
    """Closed, inward-facing corridor of ``width`` × ``height`` along a 2-D polyline ``(K, 2)``."""
    c = np.asarray(centreline, dtype=np.float64)
    direction = np.diff(c, axis=0)
    direction /= np.linalg.norm(direction, axis=1, keepdims=True)
    normal = np.column_stack([-direction[:, 1], direction[:, 0]])  # left of travel
    n_in = np.vstack([normal[:1], normal])
    n_out = np.vstack([normal, normal[-1:]])
    miter = (n_in + n_out) / (1.0 + np.sum(n_in * n_out, axis=1, keepdims=True)) * (width / 2)
    k = len(c)
    left, right = c + miter, c - miter
    ground = np.vstack([left, right])  # left i -> i, right i -> k + i
    vertices = np.vstack(
        [np.column_stack([ground, np.zeros(2 * k)]), np.column_stack([ground, np.full(2 * k, height)])]
    )
    up = 2 * k
    floor_q, ceiling_q, wall_q = [], [], []
    for i in range(k - 1):
        L0, L1, R0, R1 = i, i + 1, k + i, k + i + 1
        floor_q.append((R0, R1, L1, L0))
        ceiling_q.append((L0 + up, L1 + up, R1 + up, R0 + up))
        wall_q.append((L0, L1, L1 + up, L0 + up))
        wall_q.append((R1, R0, R0 + up, R1 + up))
    wall_q.append((k, 0, up, k + up))
    wall_q.append((k - 1, 2 * k - 1, 2 * k - 1 + up, k - 1 + up))
    faces = np.concatenate([_quads(floor_q), _quads(ceiling_q), _quads(wall_q)])
    material = np.concatenate(
        [
            np.full(2 * len(floor_q), MATERIAL_IDS[floor]),
            np.full(2 * len(ceiling_q), MATERIAL_IDS["ceiling"]),
            np.full(2 * len(wall_q), MATERIAL_IDS[walls]),
        ]
    )
    return SceneMesh(trimesh.Trimesh(vertices, faces, process=False), material)


def corridor(rng: np.random.Generator) -> SceneMesh:
    """A 2 m wide, 2.6 m high corridor, 32 m long with two right-angle turns, pillars every 2.5 m."""
    width, height = 2.0, 2.6
    centreline = np.array([(-1.0, 0.0), (14.0, 0.0), (14.0, 8.0), (25.0, 8.0)])
    parts = [tunnel(centreline, width, height, "plaster", "concrete")]
    for a, b in itertools.pairwise(centreline):
        direction = (b - a) / np.linalg.norm(b - a)
        side = np.array([-direction[1], direction[0]])
        for along in np.arange(2.5, np.linalg.norm(b - a) - 1.5, 2.5):
            for s in (-1, 1):
                x, y = a + direction * (along + rng.uniform(-0.05, 0.05)) + side * s * (width / 2 - 0.1)
                size = (0.3, 0.2) if direction[0] else (0.2, 0.3)
                parts.append(box((*size, height), (x, y, height / 2), "bricks"))
    return join_parts(parts)


#: The ``floor`` preset's corridor: five 30 m legs joined by 5 m bends, 170 m in all.
FLOOR_LEG_M, FLOOR_BEND_M, FLOOR_LEGS = 30.0, 5.0, 5


def _floor_centreline() -> np.ndarray:
    """``(2 * FLOOR_LEGS, 2)`` corners of the ``floor`` corridor: legs along x, alternating direction."""
    corners = []
    for leg in range(FLOOR_LEGS):
        ends = (0.0, FLOOR_LEG_M) if leg % 2 == 0 else (FLOOR_LEG_M, 0.0)
        corners += [(x, leg * FLOOR_BEND_M) for x in ends]
    return np.array(corners)


def _floor_path() -> tuple[tuple[float, float], ...]:
    """The robot's waypoints along the ``floor`` corridor: its corners cut by 1 m (as ``corridor``'s)
    and a waypoint every 2.5 m or less between them, so that the spline through them stays on the
    centreline (through the corners alone it swings metres off the 30 m legs, through the walls)."""
    c = _floor_centreline()
    corners = [c[0] + (0.5, 0.0)]
    for before, corner, after in zip(c[:-2], c[1:-1], c[2:], strict=True):
        into = (corner - before) / np.linalg.norm(corner - before)
        out = (after - corner) / np.linalg.norm(after - corner)
        corners += [corner - into, corner + out]
    corners.append(c[-1] - (c[-1] - c[-2]) / np.linalg.norm(c[-1] - c[-2]) * 0.5)
    points = [corners[0]]
    for a, b in itertools.pairwise(corners):
        steps = max(1, int(np.ceil(np.linalg.norm(b - a) / 2.5)))
        points += [a + (b - a) * k / steps for k in range(1, steps + 1)]
    return tuple((float(x), float(y)) for x, y in points)


def floor(rng: np.random.Generator) -> SceneMesh:
    """A floor of a building as one long corridor (2.4 m wide, 2.6 m high): five 30 m legs joined by
    5 m bends; each leg has its own wall finish, pillars every 3 m on alternating sides and a few
    boxes and cabinets along the walls, so that no two stretches look alike."""
    width, height = 2.4, 2.6
    centreline = _floor_centreline()
    parts = [tunnel(centreline, width, height, "plaster", "tiles")]
    finishes = ("bricks", "wood", "concrete", "paint_blue", "paint_red")
    for leg, (a, b) in enumerate(itertools.pairwise(centreline)):
        length = float(np.linalg.norm(b - a))
        direction = (b - a) / length
        side = np.array([-direction[1], direction[0]])
        finish = finishes[(leg // 2) % len(finishes)]  # a leg and the bend after it
        for k, along in enumerate(np.arange(2.0, length - 1.5, 3.0)):
            s = 1 if k % 2 else -1
            x, y = a + direction * (along + rng.uniform(-0.2, 0.2)) + side * s * (width / 2 - 0.12)
            size = (0.3, 0.24) if direction[0] else (0.24, 0.3)
            parts.append(box((*size, height), (x, y, height / 2), finish))
        for along in rng.uniform(1.5, length - 1.5, max(int(length // 6), 1)):
            s = rng.choice((-1, 1))
            extent = rng.uniform((0.3, 0.3, 0.4), (0.7, 0.5, 1.4))
            x, y = a + direction * along + side * s * (width / 2 - extent[1] / 2 - 0.05)
            material = ("cardboard", "metal", "fabric", "wood")[int(rng.integers(4))]
            yaw = float(np.arctan2(direction[1], direction[0]))
            parts.append(box(tuple(extent), (x, y, extent[2] / 2), material, yaw))
    return join_parts(parts)


def stairs(rng: np.random.Generator) -> SceneMesh:
    """A 7 × 5 × 3.2 m hall with a flight of five 15 cm steps up to a landing, and a few boxes."""
    parts = [shell((7.0, 5.0, 3.2), "concrete")]
    rise, tread, width = 0.15, 0.30, 1.6
    for k in range(5):
        h = rise * (k + 1)
        parts.append(box((tread, width, h), (4.0 + tread * (k + 0.5), 4.1, h / 2), "wood"))
    parts.append(
        box((1.5, width, rise * 5), (4.0 + tread * 5 + 0.75, 4.1, rise * 2.5), "concrete")
    )  # landing
    for size, centre in (((0.6, 0.6, 0.6), (0.6, 4.3)), ((0.5, 0.8, 0.4), (6.4, 0.6))):
        parts.append(box(size, (*centre, size[2] / 2), "cardboard", rng.uniform(-0.2, 0.2)))
    return join_parts(parts)


#: The chessboard of the ``boards`` preset: 7 × 5 inner corners, 10 cm squares, 5 cm margin.
CALIBRATION_BOARD = BoardSpec(cols=7, rows=5, square_m=0.10, margin_m=0.05)
#: Where the ``boards`` preset's boards stand: centre (m), facing and lean-back (degrees).
#: Each faces the robot near the end of one leg of its loop, turned and tilted differently, so
#: that the board normals spread in every direction of the rig.
BOARD_POSES = (
    ((6.3, 2.1, 0.72), 170.0, 30.0),
    ((4.9, 5.3, 0.72), -55.0, 0.0),
    ((0.7, 3.9, 0.72), -30.0, -12.0),
    ((2.1, 0.7, 0.72), 115.0, 20.0),
)


def boards(rng: np.random.Generator) -> SceneMesh:
    """A 7 × 6 × 2.6 m room with four free-standing chessboards (:data:`CALIBRATION_BOARD` at
    :data:`BOARD_POSES`) round a loop, and two boxes."""
    parts = [shell((7.0, 6.0, 2.6), "plaster")]
    parts += [SceneMesh(*board_mesh(CALIBRATION_BOARD, *pose)) for pose in BOARD_POSES]
    for size, centre in (((0.6, 0.6, 0.6), (6.2, 5.2)), ((0.5, 0.8, 0.5), (0.7, 0.8))):
        parts.append(box(size, (*centre, size[2] / 2), "cardboard", rng.uniform(-0.2, 0.2)))
    return join_parts(parts)


@dataclass(frozen=True)
class Preset:
    """A procedural scene with the path the robot drives through it and the rig's extrinsic.

    Attributes:
        build: seeded scene generator.
        waypoints: ``(K, 2)`` x, y of the robot path (z up world).
        closed: the path is a loop (driven round as often as the duration needs).
        T_cam_lidar: ``(4, 4)`` LiDAR-to-camera transform of the rig in this preset.
        speed_mps: the robot's cruising speed along the path.
        movers: seeded generator of the objects that move during the run, given the robot's
            cruising speed (none if ``None``).
        sky: an open scene: rays that miss everything see the sky.
        sensor_defaults: :class:`~rig.sim.config.SimConfig` values this preset's rig has unless
            the user sets them (carrier, LiDAR, image size, range).
    """

    name: str
    build: Callable[[np.random.Generator], SceneMesh]
    waypoints: tuple[tuple[float, float], ...]
    closed: bool
    T_cam_lidar: np.ndarray
    speed_mps: float = 0.45
    movers: Callable[[np.random.Generator, float], list[Mover]] | None = None
    sky: bool = False
    sensor_defaults: dict[str, object] = field(default_factory=dict)


def _extrinsic(rot_deg: tuple[float, float, float], t_cam: tuple[float, float, float]) -> np.ndarray:
    """A LiDAR mounted above the camera: nominal axes, a small rotation (degrees), an offset (m)."""
    R = Rotation.from_euler("xyz", rot_deg, degrees=True).as_matrix() @ R_CAM_LIDAR_NOMINAL
    return make_transform(R, t_cam)


PRESETS: dict[str, Preset] = {
    "room": Preset(
        "room",
        room,
        ((1.4, 1.3), (3.6, 1.1), (5.8, 1.5), (6.3, 3.0), (5.0, 3.4), (3.2, 2.8), (1.8, 2.4)),
        True,
        _extrinsic((1.0, -2.0, 0.5), (0.02, -0.09, -0.03)),
    ),
    "corridor": Preset(
        "corridor",
        corridor,
        ((0.5, 0.0), (7.0, 0.1), (13.0, 0.0), (14.0, 1.0), (14.0, 7.0), (15.0, 8.0), (23.0, 8.0)),
        False,
        _extrinsic((-1.5, 1.0, 0.0), (0.0, -0.12, 0.01)),
    ),
    "stairs": Preset(
        "stairs",
        stairs,
        ((1.0, 1.0), (3.0, 0.9), (4.8, 1.4), (5.2, 2.4), (4.0, 2.7), (2.5, 2.6), (1.2, 2.0)),
        True,
        _extrinsic((0.5, 1.5, -1.0), (-0.03, -0.07, -0.05)),
    ),
    "floor": Preset(
        "floor",
        floor,
        _floor_path(),
        False,
        _extrinsic((1.0, 0.5, -1.0), (0.01, -0.1, -0.02)),
        sensor_defaults={"duration_s": 120.0},
    ),
    "boards": Preset(
        "boards",
        boards,
        ((2.0, 2.0), (5.0, 2.0), (5.0, 4.0), (2.0, 4.0)),
        True,
        _extrinsic((0.8, -1.2, 0.6), (0.03, -0.08, -0.02)),
    ),
    "office": Preset(
        "office",
        office,
        OFFICE_PATH,
        True,
        _extrinsic((-0.8, 1.2, 0.4), (0.02, -0.08, -0.02)),
        speed_mps=0.5,
        sensor_defaults={"carrier": "handheld"},
    ),
    "street": Preset(
        "street",
        street,
        ((0.0, EGO_LANE_Y), (45.0, EGO_LANE_Y), (100.0, EGO_LANE_Y)),
        False,
        # KITTI's layout: the LiDAR 8 cm above and 27 cm behind the camera.
        _extrinsic((0.4, -0.6, 0.3), (0.0, -0.08, -0.27)),
        speed_mps=EGO_SPEED_MPS,
        movers=street_traffic,
        sky=True,
        sensor_defaults={
            "carrier": "car",
            "lidar": "velodyne64",
            "width": 640,
            "height": 240,
            "max_range_m": 80.0,
        },
    ),
}


def get_preset(name: str) -> Preset:
    """The preset called ``name``; raises :class:`InputError` listing the known ones."""
    if name not in PRESETS:
        raise InputError(f"unknown preset {name!r}; expected one of {', '.join(PRESETS)}", field="preset")
    return PRESETS[name]
