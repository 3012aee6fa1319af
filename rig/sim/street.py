"""The ``street`` preset: an open city street driven by a car, with traffic and sky.

World frame: z up, metres; the street runs along x. Four 3.5 m lanes (y from -7 to 7; the ego
car drives in the lane at y = -1.75 towards +x), 15 cm kerbs to 4 m pavements, building blocks
6–18 m high behind them with a cross street at x = 32–46, an overpass at x = 70–76, trees whose
crowns and lamp posts whose tops rise above a roof LiDAR's top beam, ground between and behind the
blocks, and open sky (beyond the street's ends too).

Traffic (:func:`street_traffic`): a car ahead and one behind at the ego car's speed, a lorry in
the next lane slowly overtaking it, two oncoming cars and one crossing at the side street.
"""

from __future__ import annotations

import numpy as np
import trimesh

from rig.sim.movers import Mover
from rig.sim.shapes import SceneMesh, box, join_parts
from rig.sim.textures import MATERIAL_IDS

#: Where the side street and the overpass cut the building rows (x ranges, m).
SIDE_STREET_X = (32.0, 46.0)
OVERPASS_X = (70.0, 76.0)
#: The street's extent along x (m).
STREET_X = (-40.0, 150.0)
#: The ground reaches this far either side of the street's axis (m): past the side street's ends.
GROUND_HALF_WIDTH = 60.0
#: The ego car's lane centre and speed (m/s).
EGO_LANE_Y = -1.75
EGO_SPEED_MPS = 3.0


def _building_row(rng: np.random.Generator, side: float) -> list[SceneMesh]:
    """Blocks 8–20 m long, 6–18 m high, 10 m deep behind the pavement on one ``side`` (±1)."""
    parts, x = [], STREET_X[0]
    while x < STREET_X[1]:
        length = rng.uniform(8.0, 20.0)
        x0, x1 = x, min(x + length, STREET_X[1])
        x = x1 + rng.uniform(0.0, 3.0)
        for gap in (SIDE_STREET_X, OVERPASS_X):
            x0, x1 = (x0, min(x1, gap[0])) if x0 < gap[0] else (max(x0, gap[1]), x1)
        if x1 - x0 < 3.0:
            continue
        height = rng.uniform(6.0, 18.0)
        material = str(rng.choice(["bricks", "plaster", "concrete"]))
        parts.append(box((x1 - x0, 10.0, height), ((x0 + x1) / 2, side * 16.0, height / 2), material))
    return parts


def _tree(x: float, y: float, rng: np.random.Generator) -> list[SceneMesh]:
    """A 3 m trunk and a crown of radius 1.4–1.9 m around 4.5 m up."""
    radius = rng.uniform(1.4, 1.9)
    crown = trimesh.creation.icosphere(subdivisions=1, radius=radius)
    crown.apply_translation((x, y, 3.0 + radius * 0.8))
    return [
        box((0.3, 0.3, 3.2), (x, y, 1.6 + 0.15), "wood"),
        SceneMesh(crown, np.full(len(crown.faces), MATERIAL_IDS["foliage"])),
    ]


def _lamp_post(x: float, y: float, side: float) -> list[SceneMesh]:
    """A 7 m post at the kerb with an arm over the road."""
    return [
        box((0.16, 0.16, 7.0), (x, y, 3.5 + 0.15), "metal"),
        box((0.12, 1.6, 0.12), (x, y - side * 0.8, 7.0), "metal"),
    ]


def _near(x: float, span: tuple[float, float], margin: float) -> bool:
    return span[0] - margin < x < span[1] + margin


def street(rng: np.random.Generator) -> SceneMesh:
    """The static street (see the module docstring): closed boxes, spheres for tree crowns."""
    length, centre = STREET_X[1] - STREET_X[0], sum(STREET_X) / 2
    side_width, side_centre = SIDE_STREET_X[1] - SIDE_STREET_X[0], sum(SIDE_STREET_X) / 2
    parts = [
        # Ground under everything, a centimetre below the road: seen between the building blocks
        # (without it the camera saw the sky below the horizon through every gap).
        box((length, 2 * GROUND_HALF_WIDTH, 0.2), (centre, 0.0, -0.11), "concrete"),
        box((length, 14.0, 0.2), (centre, 0.0, -0.1), "asphalt"),
        # the side street, a hair lower where it overlaps the street
        box((side_width, 100.0, 0.2), (side_centre, 0.0, -0.1001), "asphalt"),
    ]
    for side in (-1.0, 1.0):
        for x0, x1 in ((STREET_X[0], SIDE_STREET_X[0]), (SIDE_STREET_X[1], STREET_X[1])):
            parts.append(box((x1 - x0, 4.0, 0.35), ((x0 + x1) / 2, side * 9.0, -0.025), "concrete"))
        parts += _building_row(rng, side)
        for x in np.arange(STREET_X[0] + 6.0, STREET_X[1], 12.0):
            if not (_near(x, SIDE_STREET_X, 2.0) or _near(x, OVERPASS_X, 2.0)):
                parts += _tree(x + rng.uniform(-1.5, 1.5), side * 9.6, rng)
        for x in np.arange(STREET_X[0] + 12.0, STREET_X[1], 25.0):
            if not _near(x, SIDE_STREET_X, 1.0):
                parts += _lamp_post(x, side * 7.4, side)
        parts.append(box((1.0, 1.0, 5.5), (sum(OVERPASS_X) / 2, side * 9.0, 2.75 + 0.15), "concrete"))
    parts.append(box((OVERPASS_X[1] - OVERPASS_X[0], 60.0, 1.0), (sum(OVERPASS_X) / 2, 0.0, 6.4), "concrete"))
    return join_parts(parts)


#: Car and lorry sizes: length, width, height (m).
CAR = (4.3, 1.8, 1.5)
LORRY = (8.5, 2.5, 3.4)


def _vehicle(size: tuple[float, float, float], paint: str, cabin: bool) -> SceneMesh:
    """A vehicle of ``size`` in its own frame: a body on 0.3 m clearance and, for cars, a glass
    cabin on the upper 40 %."""
    length, width, height = size
    body_h = height * (0.6 if cabin else 1.0) - 0.3
    parts = [box((length, width, body_h), (0.0, 0.0, 0.3 + body_h / 2), paint)]
    if cabin:
        cabin_h = height - 0.3 - body_h
        centre = (-0.1 * length, 0.0, 0.3 + body_h + cabin_h / 2)
        parts.append(box((length * 0.55, width * 0.9, cabin_h), centre, "glass"))
    return join_parts(parts)


def street_traffic(rng: np.random.Generator, ego_speed_mps: float) -> list[Mover]:
    """The moving vehicles: each drives straight at constant speed through the whole run, the two
    in the ego car's lane at its ``ego_speed_mps``."""
    j = rng.uniform(-0.3, 0.3, 5)
    plan = (  # name, size, paint, start x/y, velocity
        ("car_ahead", CAR, "paint_red", (14.0, EGO_LANE_Y), (ego_speed_mps + 0.1 * j[0], 0.0)),
        ("car_behind", CAR, "paint_blue", (-12.0, EGO_LANE_Y), (ego_speed_mps, 0.0)),
        ("lorry_beside", LORRY, "paint_white", (-6.0, -5.25), (3.3 + 0.1 * j[1], 0.0)),
        ("oncoming_1", CAR, "paint_white", (80.0 + j[2], 1.75), (-8.0, 0.0)),
        ("oncoming_2", CAR, "paint_blue", (150.0 + j[3], 5.25), (-9.0, 0.0)),
        ("crossing", CAR, "paint_red", (39.0, -50.0 + j[4]), (0.0, 7.0)),
    )
    movers = []
    for name, size, paint, start, velocity in plan:
        vehicle = _vehicle(size, paint, cabin=size is CAR)
        movers.append(Mover(name, vehicle.mesh, vehicle.face_material, start, velocity))
    return movers
