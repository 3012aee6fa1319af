"""The stress suite without pytest: every area's checks on seeded random cases, counted per area
(cases tried, failures found, non-finite events caught). ``lts bench stability`` prints it."""

from __future__ import annotations

import tempfile
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from functools import partial
from pathlib import Path
from typing import Any

import numpy as np

from lts.stress.geometry import stress_geometry
from lts.stress.guards import crash_description
from lts.stress.photometric import stress_photometric
from lts.stress.raster import stress_raster, stress_raster_nonfinite, stress_raster_scale
from lts.stress.readers import stress_reader
from lts.stress.time_offset import stress_time_offset
from lts.stress.trajectory import stress_trajectory
from rig.errors import InputError

#: Cases per area for each profile.
PROFILES: dict[str, dict[str, int]] = {
    "ci": {
        "raster": 150,
        "raster_scale": 40,
        "raster_nonfinite": 20,
        "photometric": 60,
        "geometry": 80,
        "trajectory": 40,
        "time_offset": 6,
        "readers": 60,
    },
    "long": {
        "raster": 5000,
        "raster_scale": 1000,
        "raster_nonfinite": 200,
        "photometric": 1000,
        "geometry": 2000,
        "trajectory": 1000,
        "time_offset": 60,
        "readers": 1500,
    },
}


@dataclass
class AreaCounts:
    """Counts of one area: cases tried, failures found, non-finite events caught (a NaN/Inf or
    otherwise invalid input refused with an InputError), and the first failures' descriptions."""

    cases: int = 0
    failures: int = 0
    nonfinite_caught: int = 0
    seconds: float = 0.0
    examples: list[str] = field(default_factory=list)

    def add(self, problems: list[str], caught: bool = False) -> None:
        """Count one case: its problems (empty: it passed) and whether invalid input was caught."""
        self.cases += 1
        self.nonfinite_caught += int(caught)
        if problems:
            self.failures += 1
            if len(self.examples) < 5:
                self.examples.extend(problems[: 5 - len(self.examples)])


def _guarded(check: Callable[[], tuple[list[str], bool]]) -> tuple[list[str], bool]:
    try:
        return check()
    except Exception as exc:  # a crash is a failure to count, not the end of the suite
        return [crash_description(exc)], False


def _area_checks(rng: np.random.Generator, workdir: Path) -> dict[str, Callable[[], tuple[list[str], bool]]]:
    """Per area, in the order they run: one random case drawn from ``rng`` and checked."""
    return {
        "raster": partial(stress_raster, rng),
        "raster_scale": partial(stress_raster_scale, rng),
        "raster_nonfinite": partial(stress_raster_nonfinite, rng),
        "photometric": partial(stress_photometric, rng),
        "geometry": partial(stress_geometry, rng),
        "trajectory": partial(stress_trajectory, rng),
        "time_offset": partial(stress_time_offset, rng),
        "readers": partial(stress_reader, rng, workdir),
    }


def run_stability_suite(profile: str = "ci", seed: int = 0) -> dict[str, Any]:
    """Run the stress checks with a seeded random generator; counts per area.

    Returns ``{"profile", "seed", "seconds", "areas": {AREA: {"cases", "failures",
    "nonfinite_caught", "seconds", "examples"}}, "totals": {"cases", "failures",
    "nonfinite_caught"}}``. ``profile`` is ``"ci"`` (a few seconds) or ``"long"``.
    """
    if profile not in PROFILES:
        raise InputError(f"unknown profile {profile!r}; expected {' or '.join(PROFILES)}", field="profile")
    counts = PROFILES[profile]
    rng = np.random.default_rng(seed)
    areas: dict[str, AreaCounts] = {}
    start = time.perf_counter()
    with tempfile.TemporaryDirectory(prefix="lts-stability-") as tmp:
        for area, check in _area_checks(rng, Path(tmp)).items():
            c = areas[area] = AreaCounts()
            t0 = time.perf_counter()
            for _ in range(counts[area]):
                c.add(*_guarded(check))
            c.seconds = round(time.perf_counter() - t0, 3)
    result = {name: {**vars(c), "examples": list(c.examples)} for name, c in areas.items()}
    return {
        "profile": profile,
        "seed": seed,
        "seconds": round(time.perf_counter() - start, 3),
        "areas": result,
        "totals": {
            key: sum(c[key] for c in result.values()) for key in ("cases", "failures", "nonfinite_caught")
        },
    }
