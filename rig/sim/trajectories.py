"""Ego-centric robot paths: smooth, seeded, forward-looking camera motion through a scene.

A path is a spline through 2-D waypoints; the robot drives along it at a nominal speed with
smooth acceleration from and to rest, the camera looks along the direction of travel and small
seeded wobbles add the pitch/roll of a wheeled base or the sway and bob of a hand-held camera.
"""

from __future__ import annotations

from typing import Literal

import numpy as np
from scipy.interpolate import CubicSpline
from scipy.spatial.transform import Rotation

from rig.errors import InputError
from rig.sim.motion import Motion

Carrier = Literal["wheeled", "handheld", "car"]
#: Rotation from the OpenCV camera frame to a body frame with x forward, y left, z up.
R_BODY_CAM = np.array([[0.0, 0.0, 1.0], [-1.0, 0.0, 0.0], [0.0, -1.0, 0.0]])
#: Seconds to accelerate from rest to the nominal speed (and to brake at the end).
RAMP_S = 1.5
#: Knot spacing of the sampled poses the :class:`Motion` spline runs through (s).
KNOT_STEP_S = 0.05


def _smooth_ramp(t: np.ndarray, duration: float) -> np.ndarray:
    """Speed factor in [0, 1]: a C¹ smoothstep up over :data:`RAMP_S`, down before ``duration``."""
    ramp = min(RAMP_S, duration / 2)
    up = np.clip(t / ramp, 0.0, 1.0)
    down = np.clip((duration - t) / ramp, 0.0, 1.0)
    return np.minimum(up * up * (3 - 2 * up), down * down * (3 - 2 * down))


def _wobble(
    rng: np.random.Generator, t: np.ndarray, amplitude: float, freqs_hz: tuple[float, ...]
) -> np.ndarray:
    """Sum of sines with random phases: a smooth, bounded, seeded perturbation ``(N,)``."""
    phases = rng.uniform(0, 2 * np.pi, len(freqs_hz))
    out = sum(np.sin(2 * np.pi * f * t + p) for f, p in zip(freqs_hz, phases, strict=True))
    return amplitude * out / len(freqs_hz)


def path_motion(
    waypoints: np.ndarray,
    duration_s: float,
    *,
    rng: np.random.Generator,
    carrier: Carrier = "wheeled",
    speed_mps: float = 0.45,
    closed: bool = True,
    from_rest: bool = True,
) -> Motion:
    """Camera motion along a path through ``waypoints`` ``(K, 2)`` (x, y in the world, z up).

    A closed path is driven round as often as ``duration_s`` needs; an open one must be long
    enough. The wheeled camera rides 0.35–0.55 m high, pitched a few degrees down with a slight
    rocking; the hand-held one 1.3–1.5 m high with bob, sway and a slow look-around; the car's
    1.6–1.7 m high on the roof, level, with a little body roll and pitch. ``from_rest``: it
    accelerates from rest and brakes to a stop; otherwise it is at speed from the first instant to
    the last (a short run that moves from its first frame).
    """
    pts = np.asarray(waypoints, dtype=np.float64)
    if closed:
        pts = np.vstack([pts, pts[:1]])
    chord = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(pts, axis=0), axis=1))])
    path = CubicSpline(chord, pts, bc_type="periodic" if closed else "natural")
    length = chord[-1]

    # Distance along the path (chord parameter) as the integral of the speed profile.
    t = np.arange(0.0, duration_s + 1e-9, 1e-3)
    speed = speed_mps * (_smooth_ramp(t, duration_s) if from_rest else np.ones_like(t))
    s = np.concatenate([[0.0], np.cumsum(speed[:-1] * 1e-3)])
    if not closed and s[-1] > length:
        raise InputError(
            f"this open path is {length:.1f} m long, enough for {length / speed_mps:.0f} s; "
            f"got a duration of {duration_s:g} s",
            field="duration",
        )
    knots = np.linspace(0.0, duration_s, max(round(duration_s / KNOT_STEP_S), 1) + 1)
    # A loop starts halfway along its first leg (not at a corner), facing along it.
    u = (np.interp(knots, t, s) + chord[1] / 2) % length if closed else np.interp(knots, t, s)
    xy = path(u)
    tangent = path(u, 1)
    yaw = np.unwrap(np.arctan2(tangent[:, 1], tangent[:, 0]))

    if carrier == "wheeled":
        height = rng.uniform(0.35, 0.55)
        z = np.full_like(knots, height)
        pitch = np.deg2rad(rng.uniform(3.0, 8.0)) + _wobble(rng, knots, np.deg2rad(0.3), (2.3, 3.7))
        roll = _wobble(rng, knots, np.deg2rad(0.3), (1.9, 2.9))
        yaw = yaw + _wobble(rng, knots, np.deg2rad(4.0), (0.05, 0.11))
    elif carrier == "handheld":
        height = rng.uniform(1.3, 1.5)
        z = height + _wobble(rng, knots, 0.025, (1.8,)) + _wobble(rng, knots, 0.01, (0.3, 0.7))
        pitch = np.deg2rad(rng.uniform(10.0, 20.0)) + _wobble(rng, knots, np.deg2rad(3.0), (0.4, 0.9))
        roll = _wobble(rng, knots, np.deg2rad(2.5), (0.9, 0.35))
        yaw = yaw + _wobble(rng, knots, np.deg2rad(12.0), (0.12, 0.2))
    elif carrier == "car":
        height = rng.uniform(1.6, 1.7)
        z = height + _wobble(rng, knots, 0.01, (1.3, 2.1))
        pitch = np.deg2rad(rng.uniform(0.0, 1.0)) + _wobble(rng, knots, np.deg2rad(0.3), (0.8, 1.7))
        roll = _wobble(rng, knots, np.deg2rad(0.3), (0.6, 1.4))
        yaw = yaw + _wobble(rng, knots, np.deg2rad(0.5), (0.07, 0.13))
    else:
        raise InputError(f"unknown carrier {carrier!r}; expected wheeled, handheld or car", field="carrier")

    R_world_body = Rotation.from_euler("ZYX", np.column_stack([yaw, pitch, roll])).as_matrix()
    positions = np.column_stack([xy, z])
    return Motion(knots, positions, R_world_body @ R_BODY_CAM, at_rest=from_rest)
