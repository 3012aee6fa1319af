"""95 % intervals from a jackknife's few groups."""

from __future__ import annotations

import pytest

from calib.intervals import NORMAL_95, jackknife_interval_95


def test_the_jackknife_interval_is_students_t_for_its_few_groups() -> None:
    # 5 groups leave the variance 4 degrees of freedom: 2.78 standard deviations, not 1.96.
    assert jackknife_interval_95(5) == pytest.approx(2.776, abs=1e-3)
    assert jackknife_interval_95(8) == pytest.approx(2.365, abs=1e-3)
    assert jackknife_interval_95(20) == pytest.approx(2.093, abs=1e-3)
    assert NORMAL_95 < jackknife_interval_95(1000) < jackknife_interval_95(20) < jackknife_interval_95(5)
