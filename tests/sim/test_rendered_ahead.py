"""rig.sim.simulate.rendered_ahead: camera frames rendered on a worker thread, a few ahead."""

from __future__ import annotations

import threading

import numpy as np
import pytest

from rig.sim.simulate import FRAMES_AHEAD, rendered_ahead


def test_gives_each_render_in_turn_never_more_than_a_few_ahead() -> None:
    asked: list[int] = []
    threads: set[int] = set()

    def render(i: int) -> np.ndarray:
        asked.append(i)
        threads.add(threading.get_ident())
        return np.full((2, 3, 3), float(i))

    with rendered_ahead(render, 10) as rendered:
        for i in range(10):
            np.testing.assert_array_equal(rendered(i), np.full((2, 3, 3), float(i)))
            assert max(asked) <= i + FRAMES_AHEAD
    assert asked == list(range(10))
    assert threading.get_ident() not in threads


def test_a_render_that_fails_raises_in_the_caller() -> None:
    def render(i: int) -> np.ndarray:
        if i == 2:
            raise ValueError("frame 2 failed")
        return np.zeros(1)

    with pytest.raises(ValueError, match="frame 2 failed"), rendered_ahead(render, 5) as rendered:
        for i in range(5):
            rendered(i)
