"""The compiled form of the photo-consistency cost's per-point sums (``csrc/``), built once;
:meth:`calib.photo_consistency._Problem.point_sums`' NumPy form is its specification and stands
in where no compiler is at hand."""

from __future__ import annotations

from functools import cache
from pathlib import Path
from types import ModuleType

from rig.native_build import NativeBuildError, load_extension

SOURCE = Path(__file__).parent / "csrc" / "photo_consistency_cpu.cpp"


@cache
def photo_extension() -> ModuleType | None:
    """The compiled extension (built on first use), or None where it cannot be built."""
    try:
        return load_extension(
            "lts_calib_cpu", [SOURCE], [], "the calibration's photo-consistency kernel",
            "The calibration's NumPy form runs instead.", build_s=15,
        )  # fmt: skip
    except NativeBuildError:
        return None
