"""Plain Python data from nested containers holding numpy values (for YAML and JSON output)."""

from __future__ import annotations

import math
from typing import Any

import numpy as np


def plain_data(value: Any, nonfinite_as_none: bool = False) -> Any:
    """``value`` with numpy arrays/scalars turned into lists/numbers, recursively through dicts,
    lists and tuples; with ``nonfinite_as_none``, NaN and ±Inf become None (JSON has no NaN)."""
    if isinstance(value, dict):
        return {str(k): plain_data(v, nonfinite_as_none) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [plain_data(v, nonfinite_as_none) for v in value]
    if isinstance(value, np.ndarray):
        return plain_data(value.tolist(), nonfinite_as_none)
    if isinstance(value, np.generic):
        return plain_data(value.item(), nonfinite_as_none)
    if nonfinite_as_none and isinstance(value, float) and not math.isfinite(value):
        return None
    return value
