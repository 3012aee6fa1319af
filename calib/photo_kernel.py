"""The compiled form of the photo-consistency cost's per-point sums and of the frames' visibility
(``csrc/``), built once; :meth:`calib.photo_consistency._Problem.point_sums`' and
:func:`calib.photo_consistency._shown_points`' NumPy forms are their specification and stand in
where no compiler is at hand."""

from __future__ import annotations

from functools import cache
from pathlib import Path
from types import ModuleType

from rig.native_build import NativeBuildError, load_extension

CSRC = Path(__file__).parent / "csrc"
SOURCES = [CSRC / "photo_consistency_cpu.cpp", CSRC / "visibility_cpu.cpp"]
HEADERS = [CSRC / "parallel_blocks.h", CSRC / "pinhole.h"]


@cache
def photo_extension() -> ModuleType | None:
    """The compiled extension (built on first use), or None where it cannot be built."""
    try:
        return load_extension(
            "lts_calib_cpu", SOURCES, HEADERS, "the calibration's photo-consistency kernels",
            "The calibration's NumPy form runs instead.", build_s=15,
        )  # fmt: skip
    except NativeBuildError:
        return None
