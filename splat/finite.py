"""Whether a tensor holds only finite values, in one pass over it.

``torch.isfinite(t).all()`` fills full-size temporaries (a NaN test, an absolute value, an
infinity test, their conjunction) before it reduces: 0.49 ms for 360 000 float32 values on this
2-core machine, and training checks about 1.3 M values an iteration (the render's inputs and the
step's gradients). The smallest and largest value, found in one pass (0.05 ms), are NaN when any
value is and infinite when any value is.
"""

from __future__ import annotations

import torch
from torch import Tensor


def all_finite(t: Tensor) -> bool:
    """True when every value of ``t`` (any shape) is finite (always for integer and empty tensors)."""
    if not t.is_floating_point() or t.numel() == 0:
        return True
    smallest, largest = torch.aminmax(t)
    return bool(torch.isfinite(smallest) & torch.isfinite(largest))
