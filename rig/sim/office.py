"""The ``office`` preset: a furnished office with the detail photometric reconstruction needs.

A 9 × 7 × 2.8 m room walked through with a hand-held rig. Curved and thin things (office chairs
on five-legged bases, plants with leaves, floor and pendant lamps on thin poles, monitors on
stands), depth discontinuities (bookcases filled with books, desks over a carpet, a round table
with the room behind it) and photographic textures (a brick wall, a carpet, leaves, posters and
monitor pictures from ``skimage.data``) next to the procedural ones.

World frame: z up, metres; the walls are x = 0, x = 9, y = 0 and y = 7. Furniture stands along
the walls and round a table in the middle; the path loops between them.
"""

from __future__ import annotations

import itertools

import numpy as np
import trimesh
from scipy.spatial.transform import Rotation

from rig.sim.shapes import (
    SceneMesh,
    box,
    curved_panel,
    cylinder,
    ellipsoid,
    join_parts,
    placed,
    revolved,
    shell,
    solid,
)
from rig.sim.textures import MATERIAL_IDS
from rig.transforms import make_transform

#: The room's extent (m).
OFFICE_SIZE = (9.0, 7.0, 2.8)
#: The hand-held rig's loop between the furniture (x, y).
OFFICE_PATH = ((2.0, 2.0), (4.5, 1.8), (7.0, 2.0), (7.3, 3.5), (7.0, 5.0), (4.5, 5.3), (2.0, 5.0), (1.7, 3.5))
#: The materials book covers are drawn from.
BOOK_MATERIALS = ("paint_red", "paint_blue", "paint_white", "cardboard", "fabric", "wood")
#: Height of desk and table tops (m).
DESK_HEIGHT = 0.74


def office_shell() -> SceneMesh:
    """Inward-facing walls (plaster, a brick wall at x = 0), a carpet and the ceiling."""
    walls = shell(OFFICE_SIZE, "plaster", floor="carpet")
    walls.face_material[walls.mesh.face_normals[:, 0] > 0.5] = MATERIAL_IDS["brick_photo"]
    return walls


def desk(rng: np.random.Generator, screen: str = "screen") -> list[SceneMesh]:
    """A 1.4 × 0.7 m desk (local frame: its back edge along y = 0.35, the user at -y) with a
    monitor on a stand, a keyboard, a mug and a few papers."""
    top = 0.03
    parts = [box((1.4, 0.7, top), (0.0, 0.0, DESK_HEIGHT - top / 2), "wood")]
    for sx in (-1, 1):  # two panel legs
        parts.append(box((0.03, 0.64, DESK_HEIGHT - top), (sx * 0.66, 0.0, (DESK_HEIGHT - top) / 2), "metal"))
    parts.append(box((1.26, 0.02, 0.4), (0.0, 0.3, 0.45), "metal"))  # modesty panel
    mx = rng.uniform(-0.25, 0.25)
    parts += [
        box((0.22, 0.16, 0.012), (mx, 0.15, DESK_HEIGHT + 0.006), "metal"),  # monitor foot
        box((0.04, 0.03, 0.16), (mx, 0.2, DESK_HEIGHT + 0.09), "metal"),  # its neck
        box((0.6, 0.04, 0.36), (mx, 0.2, DESK_HEIGHT + 0.33), "metal"),  # the monitor's body
        box((0.56, 0.006, 0.32), (mx, 0.178, DESK_HEIGHT + 0.33), screen),  # its picture
        box((0.44, 0.14, 0.02), (mx, -0.15, DESK_HEIGHT + 0.01), "paint_white"),  # keyboard
        cylinder(0.04, 0.1, (mx + 0.45, -0.1, DESK_HEIGHT), "paint_blue"),  # mug
    ]
    for _ in range(int(rng.integers(1, 4))):  # papers
        x, y = rng.uniform(-0.6, -0.3), rng.uniform(-0.25, 0.2)
        parts.append(
            box((0.21, 0.297, 0.004), (x, y, DESK_HEIGHT + 0.002), "paint_white", rng.uniform(-0.5, 0.5))
        )
    return parts


def office_chair(rng: np.random.Generator) -> list[SceneMesh]:
    """A swivel chair (local frame, facing -y): five legs on castors, a column, a round seat and a
    curved backrest."""
    parts = []
    for k in range(5):
        a = 2 * np.pi * k / 5 + rng.uniform(0, 0.3)
        c, s = np.cos(a), np.sin(a)
        parts.append(box((0.3, 0.04, 0.03), (0.15 * c, 0.15 * s, 0.07), "metal", a))
        parts.append(cylinder(0.025, 0.05, (0.29 * c, 0.29 * s, 0.0), "fabric", 12))  # castor
    parts.append(cylinder(0.025, 0.36, (0.0, 0.0, 0.08), "metal", 16))
    parts.append(cylinder(0.24, 0.07, (0.0, 0.0, 0.44), "fabric", 32))
    # The backrest: a 100° arc of a ring 0.23-0.27 m round the seat's axis, behind it (+y).
    arc = (np.deg2rad(40.0), np.deg2rad(140.0))
    parts.append(curved_panel((0.23, 0.27), 0.48, arc, (0.0, 0.0, 0.55), "fabric"))
    parts.append(box((0.04, 0.03, 0.1), (0.0, 0.24, 0.53), "metal"))
    return parts


def plant(rng: np.random.Generator, tall: bool) -> list[SceneMesh]:
    """A pot (a tapered ring with soil) and stems carrying flat leaves; ``tall``: a 1.5 m plant
    on the floor, otherwise a 0.5 m one."""
    h = 0.4 if tall else 0.16
    r = 0.18 if tall else 0.08
    parts = [
        revolved([(0.0, 0.0), (0.8 * r, 0.0), (r, h), (0.0, h)], (0.0, 0.0, 0.0), "cardboard"),
        cylinder(0.93 * r, 0.01, (0.0, 0.0, h - 0.015), "concrete"),
    ]
    stems = int(rng.integers(5, 8)) if tall else 4
    for _ in range(stems):
        length = rng.uniform(0.6, 1.2) if tall else rng.uniform(0.15, 0.3)
        lean = rng.uniform(0.1, 0.35)
        heading = rng.uniform(0, 2 * np.pi)
        R = Rotation.from_euler("ZY", (heading, lean)).as_matrix()
        stem = cylinder(0.008 if tall else 0.004, length, (0.0, 0.0, 0.0), "wood", 8)
        parts.append(SceneMesh(stem.mesh.apply_transform(make_transform(R, (0, 0, h))), stem.face_material))
        for k in range(3 if tall else 2):  # leaves along the upper part of the stem
            along = length * (0.55 + 0.2 * k)
            centre = R @ np.array([0.0, 0.0, along]) + (0.0, 0.0, h)
            leaf_len = rng.uniform(0.12, 0.22) if tall else rng.uniform(0.05, 0.09)
            turn = Rotation.from_euler("ZYX", (rng.uniform(0, 2 * np.pi), rng.uniform(-0.6, 0.6), 0.0))
            T = make_transform(turn.as_matrix(), centre)
            parts.append(ellipsoid((leaf_len, leaf_len * 0.35, 0.006), T, "leaves", 2))
    return parts


def floor_lamp() -> list[SceneMesh]:
    """A 1.6 m lamp: a round foot, a thin pole and a conical shade."""
    return [
        cylinder(0.15, 0.02, (0.0, 0.0, 0.0), "metal", 32),
        cylinder(0.012, 1.45, (0.0, 0.0, 0.02), "metal", 12),
        revolved([(0.0, 0.0), (0.22, 0.0), (0.12, 0.26), (0.0, 0.26)], (0.0, 0.0, 1.38), "paint_white"),
    ]


def pendant_lamp(xy: tuple[float, float]) -> list[SceneMesh]:
    """A shade hung from the ceiling on a thin cable over ``xy``."""
    top = OFFICE_SIZE[2]
    return [
        cylinder(0.004, 0.9, (*xy, top - 0.9), "metal", 8),
        revolved([(0.0, 0.0), (0.25, 0.0), (0.08, 0.18), (0.0, 0.18)], (*xy, top - 1.05), "paint_red"),
    ]


def bookcase(rng: np.random.Generator, width: float = 1.6, height: float = 2.0) -> list[SceneMesh]:
    """A bookcase (local frame: its back against y = +0.17, open towards -y) with five shelves of
    books, some leaning, and a few boxes and ornaments."""
    depth, board = 0.34, 0.02
    parts = [
        box((board, depth, height), (sx * (width / 2 - board / 2), 0.0, height / 2), "wood") for sx in (-1, 1)
    ]
    parts.append(box((width, 0.01, height), (0.0, depth / 2 - 0.005, height / 2), "wood"))  # back
    levels = np.linspace(0.05, height - board / 2, 6)
    for z in levels:
        parts.append(box((width - 2 * board, depth - 0.01, board), (0.0, 0.0, z), "wood"))
    for z0, z1 in itertools.pairwise(levels):
        x = -width / 2 + board + rng.uniform(0.0, 0.1)
        room = z1 - z0 - board
        while x < width / 2 - board - 0.06:
            if rng.uniform() < 0.12:  # a gap, a box or an ornament
                size = rng.uniform(0.08, 0.22)
                if rng.uniform() < 0.5:
                    parts.append(
                        box(
                            (size, 0.2, min(size, room - 0.02)),
                            (x + size / 2, 0.0, z0 + board / 2 + min(size, room - 0.02) / 2),
                            "cardboard",
                            rng.uniform(-0.3, 0.3),
                        )
                    )
                else:
                    T = make_transform(np.eye(3), (x + size / 2, 0.0, z0 + board / 2 + 0.05))
                    parts.append(ellipsoid((0.05, 0.05, 0.05), T, "paint_blue", 2))
                x += size + 0.03
                continue
            w = rng.uniform(0.02, 0.06)
            h = rng.uniform(0.55, 0.9) * room
            d = rng.uniform(0.16, 0.26)
            material = BOOK_MATERIALS[int(rng.integers(len(BOOK_MATERIALS)))]
            lean = rng.uniform(0.15, 0.35) if rng.uniform() < 0.1 else 0.0
            R = Rotation.from_euler("y", lean).as_matrix()
            T = make_transform(
                R,
                (
                    x + w / 2 + h * np.sin(lean) / 2,
                    -depth / 2 + d / 2 + 0.02,
                    z0 + board / 2 + h * np.cos(lean) / 2,
                ),
            )
            parts.append(solid(trimesh.creation.box(extents=(w, d, h)), material, T))
            x += w + h * np.sin(lean) + 0.002
    return parts


def round_table(rng: np.random.Generator) -> list[SceneMesh]:
    """A 1.2 m round table on one column and a cross foot, with a vase of flowers."""
    parts = [
        cylinder(0.6, 0.03, (0.0, 0.0, DESK_HEIGHT - 0.03), "wood", 48),
        cylinder(0.04, DESK_HEIGHT - 0.05, (0.0, 0.0, 0.02), "metal", 16),
        box((0.7, 0.06, 0.02), (0.0, 0.0, 0.01), "metal"),
        box((0.06, 0.7, 0.02), (0.0, 0.0, 0.01), "metal"),
        revolved(
            [(0.0, 0.0), (0.05, 0.0), (0.07, 0.08), (0.03, 0.2), (0.0, 0.2)],
            (0.15, 0.1, DESK_HEIGHT),
            "glass",
        ),
    ]
    parts += placed(plant(rng, tall=False)[2:], (0.15, 0.1), 0.0, DESK_HEIGHT + 0.04)  # flowers in it
    return parts


def wall_picture(
    corner: tuple[float, float, float], wall: str, material: str, size: float = 0.8
) -> SceneMesh:
    """A 2 cm deep picture on the wall ``x0`` (x = 0) or ``y1`` (y = 7) whose lower left corner, as
    seen from the room, is ``corner``. Textures are laid in world coordinates: a corner on multiples
    of ``size`` shows the picture once, another a wrapped part of it (the office's pictures hang
    at 1.2 m, so they show the lower half of their picture above the upper half)."""
    x, y, z = corner
    if wall == "x0":
        return box((0.02, size, size), (0.01, y + size / 2, z + size / 2), material)
    return box((size, 0.02, size), (x + size / 2, OFFICE_SIZE[1] - 0.01, z + size / 2), material)


def office(rng: np.random.Generator) -> SceneMesh:
    """The ``office`` preset's scene (see the module's docstring)."""
    W, D, _ = OFFICE_SIZE
    parts = [office_shell()]
    # Two desks with chairs against the wall y = 0, one against x = 9.
    for x, screen in ((2.1, "screen"), (4.1, "poster_coffee")):
        parts += placed(desk(rng, screen), (x, 0.36), np.pi)
        parts += placed(office_chair(rng), (x + rng.uniform(-0.2, 0.2), 1.05), np.pi + rng.uniform(-0.4, 0.4))
    parts += placed(desk(rng, "poster_chelsea"), (W - 0.36, 4.6), -np.pi / 2)
    parts += placed(office_chair(rng), (W - 1.05, 4.7), -np.pi / 2 + rng.uniform(-0.4, 0.4))
    # Bookcases against the walls y = 0 and y = 7.
    parts += placed(bookcase(rng), (6.4, 0.18), np.pi)
    parts += placed(bookcase(rng, 1.2, 1.8), (5.4, D - 0.18), 0.0)
    # A sofa-like bench and a cabinet with a plant on it.
    parts.append(box((1.8, 0.7, 0.42), (2.9, D - 0.4, 0.21), "fabric"))
    parts.append(box((1.8, 0.2, 0.45), (2.9, D - 0.1, 0.64), "fabric"))
    parts.append(box((0.5, 1.2, 0.9), (0.26, 4.3, 0.45), "wood"))
    parts += placed(plant(rng, tall=False), (0.26, 4.0), 0.0, 0.9)
    # Tall plants in corners, lamps, a round table with two chairs and a lamp over it.
    for xy in ((W - 0.6, 0.6), (W - 0.6, D - 0.6), (0.6, 1.0)):
        parts += placed(plant(rng, tall=True), xy, rng.uniform(0, 2 * np.pi))
    for xy in ((7.6, 0.45), (1.0, D - 0.5)):
        parts += placed(floor_lamp(), xy, 0.0)
    parts += placed(round_table(rng), (4.5, 3.5), rng.uniform(0, 2 * np.pi))
    for x, yaw in ((3.55, -np.pi / 2), (5.45, np.pi / 2)):
        parts += placed(office_chair(rng), (x, 3.5), yaw + rng.uniform(-0.3, 0.3))
    parts += pendant_lamp((4.5, 3.5))
    # A whiteboard on the wall x = 9 and pictures on the walls x = 0 and y = 7.
    parts.append(box((0.02, 1.8, 1.1), (W - 0.01, 2.4, 1.45), "paint_white"))
    parts.append(wall_picture((0.0, 2.4, 1.2), "x0", "poster_astronaut"))
    parts.append(wall_picture((1.6, 0.0, 1.2), "y1", "poster_chelsea"))
    parts.append(wall_picture((7.2, 0.0, 1.2), "y1", "poster_coffee"))
    # A waste bin.
    parts.append(revolved([(0.0, 0.0), (0.13, 0.0), (0.16, 0.35), (0.0, 0.35)], (0.35, 2.4, 0.0), "metal"))
    return join_parts(parts)
