"""lts.demo.import_while_recording: the reconstruction's modules load beside the recorder."""

from __future__ import annotations

import sys

import pytest

from lts import demo


def test_imports_every_module_and_leaves_a_missing_one_to_its_stage(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(demo, "RECONSTRUCTION_MODULES", ("no_such_module_of_lts", "json", "splat.trainer"))
    thread = demo.import_while_recording()
    thread.join(timeout=120)
    assert not thread.is_alive() and thread.daemon
    assert "splat.trainer" in sys.modules and "no_such_module_of_lts" not in sys.modules


def test_the_modules_exist() -> None:
    import importlib.util

    assert all(importlib.util.find_spec(name) is not None for name in demo.RECONSTRUCTION_MODULES)
