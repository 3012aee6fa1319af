"""Stress suite (issue 11): hypothesis profiles, an in-process CLI runner, small sample files.

Profiles: ``stress-ci`` (the default: short, for CI's time budget) and ``stress-long`` (a bug
hunt, selected with ``HYPOTHESIS_PROFILE=long``). They are registered under their own names so
that loading them here does not change the ``ci``/``long`` profiles the rest of the suite uses;
tests in this folder take their settings from :data:`STRESS` explicitly.
"""

from __future__ import annotations

import os
import sys
from collections.abc import Callable
from pathlib import Path

import pytest
from hypothesis import HealthCheck, settings

sys.path.insert(0, str(Path(__file__).parent))  # --import-mode=importlib: make helpers importable


_QUIET = [HealthCheck.too_slow, HealthCheck.function_scoped_fixture, HealthCheck.data_too_large]
settings.register_profile(
    "stress-ci", max_examples=30, deadline=None, derandomize=True, suppress_health_check=_QUIET
)
settings.register_profile("stress-long", max_examples=1500, deadline=None, suppress_health_check=_QUIET)
LONG = os.environ.get("HYPOTHESIS_PROFILE") == "long"
#: The settings every property test here uses (``@STRESS``); ``examples(n)`` scales a per-test
#: count, which the long profile multiplies by 50.
STRESS = settings.get_profile("stress-long" if LONG else "stress-ci")


def examples(n: int) -> settings:
    """Settings with ``n`` examples in CI (``50 n`` in the long profile)."""
    return settings(STRESS, max_examples=n * 50 if LONG else n)


def assert_one_line_error(code: int, err: str, *needles: str) -> None:
    """Exit status 2 and a single stderr line that holds every needle, with no traceback."""
    assert code == 2, err
    assert "Traceback" not in err, err
    lines = [line for line in err.strip().splitlines() if line.strip()]
    assert len(lines) == 1, err
    for needle in needles:
        assert needle in lines[0], (needle, lines[0])


@pytest.fixture(scope="session")
def samples(tmp_path_factory: pytest.TempPathFactory) -> Callable[[str], Path]:
    """``samples(kind)``: a small valid file of ``kind`` (see lts.stress.samples.READER_KINDS)."""
    from lts.stress.samples import sample_suffix, write_sample

    root = tmp_path_factory.mktemp("samples")
    made: dict[str, Path] = {}

    def get(kind: str) -> Path:
        if kind not in made:
            made[kind] = write_sample(kind, root / f"{kind}{sample_suffix(kind)}")
        return made[kind]

    return get
