"""The stress suite's support pieces: its guards, its counting, its valid samples and its package
exports."""

from __future__ import annotations

import subprocess
import sys
import time
from pathlib import Path

import pytest

from lts.stress.guards import crash_description, time_limit
from lts.stress.readers import check_reader
from lts.stress.samples import READER_KINDS
from lts.stress.suite import AreaCounts


def _fail(message: str) -> None:
    raise ValueError(message)


def test_crash_description_names_the_type_the_message_and_the_raising_line() -> None:
    try:
        _fail("x" * 200)
    except ValueError as exc:
        text = crash_description(exc)
    line = _fail.__code__.co_firstlineno + 1
    assert text == f"ValueError: {'x' * 120} ({Path(__file__).name}:{line})"


def test_time_limit_turns_a_hang_into_a_timeout_error_and_restores_the_alarm() -> None:
    with pytest.raises(TimeoutError, match="a hang"), time_limit(0.05):
        time.sleep(2.0)
    with time_limit(1.0):  # a block that ends in time is left alone
        pass


def test_area_counts_count_cases_failures_caught_inputs_and_keep_five_examples() -> None:
    counts = AreaCounts()
    counts.add([], caught=True)
    counts.add(["a", "b", "c"])
    counts.add(["d", "e", "f"])
    counts.add([])
    assert (counts.cases, counts.failures, counts.nonfinite_caught) == (4, 2, 1)
    assert counts.examples == ["a", "b", "c", "d", "e"]


@pytest.mark.parametrize("kind", READER_KINDS)
def test_an_undamaged_sample_reads_back_clean(kind: str, tmp_path: Path) -> None:
    """An empty overwrite leaves the sample as written: its reader must take it without a problem."""
    assert check_reader(kind, "flip", 0.0, b"", tmp_path) == ([], False)


def test_the_package_exports_resolve_without_loading_torch_on_import() -> None:
    code = (
        "import sys, lts.stress as s; assert 'torch' not in sys.modules, 'torch on import';"
        "[getattr(s, name) for name in s.__all__]"
    )
    result = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert result.returncode == 0, result.stderr
