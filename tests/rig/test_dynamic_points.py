"""The see-through test: points of a vehicle driving past a LiDAR are dynamic, the street's are not."""

from __future__ import annotations

import numpy as np
import trimesh
from scipy.spatial.distance import cdist

from rig.dynamic_points import DynamicConfig, comparison_sweeps, dynamic_mask, grown, on_ground, sweep_view
from rig.sim.movers import Mover, MovingRaycaster, inside_movers


def _scene() -> tuple[trimesh.Trimesh, Mover]:
    """A ground plane, a wall 12 m to the side and a 4 m car driving past at 3 m/s, 5 m away."""
    ground = trimesh.creation.box(extents=(80.0, 40.0, 0.2))
    ground.apply_translation((0.0, 0.0, -0.1))
    wall = trimesh.creation.box(extents=(80.0, 0.5, 6.0))
    wall.apply_translation((0.0, -12.0, 3.0))
    car = trimesh.creation.box(extents=(4.0, 1.8, 1.4))
    car.apply_translation((0.0, 0.0, 1.0))
    mover = Mover("car", car, np.zeros(len(car.faces), dtype=np.int64), (-4.0, -5.0), (3.0, 0.0))
    return trimesh.util.concatenate([ground, wall]), mover


def _sweep(
    caster: MovingRaycaster, t: float, xy: tuple[float, float], beams: tuple[float, float, int] = (-25, 5, 32)
) -> tuple[np.ndarray, np.ndarray]:
    """Sensor-frame points ``(N, 3)`` of a sweep from 1.7 m up (``beams``: lowest and highest
    elevation in degrees, count), and their world points."""
    elevation, azimuth = np.meshgrid(np.radians(np.linspace(*beams)), np.radians(np.arange(0, 360, 0.4)))
    d = np.column_stack(
        [(np.cos(elevation) * np.cos(azimuth)).ravel(), (np.cos(elevation) * np.sin(azimuth)).ravel(),
         np.sin(elevation).ravel()]
    )  # fmt: skip
    origin = np.array([*xy, 1.7])
    hits = caster.cast(origin, d, t)
    ok = hits.hit & (hits.distance < 60)
    return d[ok] * hits.distance[ok, None], hits.points[ok]


def _dynamic_at_2s(
    static: trimesh.Trimesh, car: Mover, config: DynamicConfig, beams: tuple[float, float, int] = (-25, 5, 32)
) -> tuple[np.ndarray, np.ndarray]:
    """The dynamic mask ``(N,)`` of the sweep at t = 2 s of a sensor driving along x at 1 m/s,
    sweeping every 0.5 s, and which of its points ``(N,)`` lie on the car."""
    caster = MovingRaycaster(static, (car,))
    times = np.arange(0.0, 4.01, 0.5)
    views, world = [], []
    for t in times:
        xy = (1.0 * t, 0.0)
        sensor, points = _sweep(caster, t, xy, beams)
        T = np.eye(4)
        T[:2, 3] = xy
        views.append(sweep_view(float(t), sensor, T, config))
        world.append(points)
    index = 4  # t = 2 s: compared with 0, 1, 1.5, 2.5, 3 and 4 s
    assert comparison_sweeps(index, times, config) == [3, 5, 2, 6, 0, 8]
    others = [views[j] for j in comparison_sweeps(index, times, config)]
    return dynamic_mask(views[index], others, config), inside_movers(
        world[index], (car,), np.array([2.0]), 0.05
    )


def test_a_passing_car_is_seen_through_and_the_street_is_not() -> None:
    dynamic, on_car = _dynamic_at_2s(*_scene(), DynamicConfig())
    assert on_car.sum() > 100
    assert dynamic[on_car].mean() > 0.9
    assert dynamic[~on_car].mean() < 0.005


def test_the_lower_half_of_a_far_car_is_grown_from_its_upper_half_not_into_the_road() -> None:
    """A car crossing 24 m ahead, its body 0.3-1.5 m above the road, seen by 64 beams from -24.8 to
    +2 degrees: below its points the next beam meets the road within the margin, so the
    see-through test alone misses its lower part; growing the mask in the sweep finds it."""
    static, _ = _scene()
    body = trimesh.creation.box(extents=(4.3, 1.8, 1.2))
    body.apply_translation((0.0, 0.0, 0.9))
    car = Mover("car", body, np.zeros(len(body.faces), dtype=np.int64), (26.0, -10.0), (0.0, 4.0))
    beams = (-24.8, 2.0, 64)
    seen_through, on_car = _dynamic_at_2s(static, car, DynamicConfig(grow_m=0.0), beams)
    dynamic, on_car = _dynamic_at_2s(static, car, DynamicConfig(), beams)
    assert on_car.sum() > 100
    assert seen_through[on_car].mean() < 0.8
    assert dynamic[on_car].mean() > 0.97
    assert dynamic[~on_car].mean() < 0.005


def test_without_comparison_sweeps_nothing_is_dynamic() -> None:
    static, car = _scene()
    sensor, _ = _sweep(MovingRaycaster(static, (car,)), 0.0, (0.0, 0.0))
    view = sweep_view(0.0, sensor, np.eye(4), DynamicConfig())
    assert not dynamic_mask(view, [], DynamicConfig()).any()


def test_a_lone_seed_on_a_wall_does_not_grow_and_a_crowd_of_them_takes_the_rest_of_their_object() -> None:
    """Sensor frame, z up, 1.7 m above the floor: a wall 3 m ahead sampled every 2 cm with one
    seed on it; a box 10 m ahead whose upper half is all seeds."""
    v, w = np.meshgrid(np.arange(-2.0, 2.0, 0.02), np.arange(-1.7, 1.0, 0.02))
    wall = np.column_stack([np.full(v.size, 3.0), v.ravel(), w.ravel()])
    u, h = np.meshgrid(np.arange(-1.0, 1.0, 0.05), np.arange(-1.4, 0.0, 0.05))  # 0.3-1.7 m up
    box = np.column_stack([np.full(u.size, 10.0), u.ravel(), h.ravel()])
    x, y = np.meshgrid(np.arange(4.0, 14.0, 0.1), np.arange(-3.0, 3.0, 0.1))
    floor = np.column_stack([x.ravel(), y.ravel(), np.full(x.size, -1.7)])
    points = np.concatenate([wall, box, floor])
    seeds = np.zeros(len(points), dtype=bool)
    seeds[len(wall) // 2] = True
    on_box = np.arange(len(points)) >= len(wall)
    on_box[len(wall) + len(box) :] = False
    seeds[on_box & (points[:, 2] > -0.7)] = True
    dynamic = grown(points, seeds, DynamicConfig())
    assert dynamic[: len(wall)].sum() == 1
    assert dynamic[on_box].mean() > 0.9
    assert not dynamic[len(wall) + len(box) :].any()


def test_growth_is_the_share_of_seeds_among_the_neighbours() -> None:
    """Off the ground, a point joins exactly where at least ``grow_support`` of its neighbours
    within ``grow_m`` (itself included) are seeds: the brute-force count over all pairs."""
    rng = np.random.default_rng(3)
    points = rng.uniform((0.0, -3.0, -1.2), (6.0, 3.0, 1.0), (2000, 3))
    seeds = (np.linalg.norm(points[:, :2] - (3.0, 0.0), axis=1) < 0.7) & (rng.random(2000) < 0.4)
    seeds[rng.choice(2000, 5, replace=False)] = True  # strays, as a static room's sweeps have
    config = DynamicConfig()
    near_pairs = cdist(points, points) <= config.grow_m
    share = (near_pairs & seeds[None]).sum(axis=1) / near_pairs.sum(axis=1)
    grows = ~seeds & (share >= config.grow_support) & ~on_ground(points, config)
    dynamic = grown(points, seeds, config)
    assert (grows & ~dynamic).sum() == 0 and (dynamic & ~seeds & ~grows).sum() == 0
    assert grows.sum() > 50  # the test is not empty
