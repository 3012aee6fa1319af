"""all_finite agrees with torch.isfinite(t).all() on finite values, NaN, either infinity, both
infinities together and the largest float32 values."""

import pytest
import torch

from splat.finite import all_finite


@pytest.mark.parametrize("dtype", [torch.float32, torch.float64])
def test_all_finite_matches_isfinite(dtype: torch.dtype) -> None:
    big = torch.finfo(dtype).max
    values = torch.randn(1000, 3, dtype=dtype)
    cases = [values, torch.full((100_000,), big, dtype=dtype), torch.zeros(0, dtype=dtype)]
    for bad in (float("nan"), float("inf"), -float("inf")):
        spoiled = values.clone()
        spoiled[500, 1] = bad
        cases.append(spoiled)
    both = values.clone()
    both[0, 0], both[1, 1] = float("inf"), -float("inf")
    cases.append(both)
    for t in cases:
        assert all_finite(t) == bool(torch.isfinite(t).all())


def test_integer_tensors_are_finite() -> None:
    assert all_finite(torch.arange(10))
