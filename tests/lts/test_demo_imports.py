"""lts.demo.import_while_recording: the reconstruction's modules load, and its extensions build,
beside the recorder."""

from __future__ import annotations

import os
import sys
import threading
import types

import pytest

from lts import demo
from rig.native_build import NativeBuildError


def test_imports_every_module_and_leaves_a_missing_one_to_its_stage(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(demo, "RECONSTRUCTION_MODULES", ("no_such_module_of_lts", "json", "splat.trainer"))
    monkeypatch.setattr(demo, "EXTENSION_LOADERS", ())
    thread = demo.import_while_recording()
    thread.join(timeout=120)
    assert not thread.is_alive() and thread.daemon
    assert "splat.trainer" in sys.modules and "no_such_module_of_lts" not in sys.modules


def test_extensions_build_below_the_recorders_priority(monkeypatch: pytest.MonkeyPatch) -> None:
    calls: list[tuple[str, int]] = []

    def loader(name: str):
        def load() -> None:
            calls.append((name, os.getpriority(os.PRIO_PROCESS, threading.get_native_id())))
            if name == "fails":
                raise NativeBuildError("no compiler here")

        return load

    fake = types.ModuleType("fake_extensions_of_lts")
    fake.fails, fake.builds = loader("fails"), loader("builds")
    monkeypatch.setitem(sys.modules, fake.__name__, fake)
    monkeypatch.setattr(demo, "RECONSTRUCTION_MODULES", ("json",))
    monkeypatch.setattr(demo, "EXTENSION_LOADERS", (f"{fake.__name__}:fails", f"{fake.__name__}:builds"))
    before = os.getpriority(os.PRIO_PROCESS, 0)
    thread = demo.import_while_recording()
    thread.join(timeout=60)
    assert not thread.is_alive()
    niceness = demo.BUILD_NICENESS if sys.platform.startswith("linux") else before
    assert calls == [("fails", niceness), ("builds", niceness)]  # a failed build leaves the next one
    assert os.getpriority(os.PRIO_PROCESS, 0) == before  # the process itself keeps its priority


def test_the_modules_and_extension_loaders_exist() -> None:
    import importlib
    import importlib.util

    assert all(importlib.util.find_spec(name) is not None for name in demo.RECONSTRUCTION_MODULES)
    for loader in demo.EXTENSION_LOADERS:
        module, function = loader.split(":")
        assert callable(getattr(importlib.import_module(module), function))
