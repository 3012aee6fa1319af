"""open3d without the import cost of its notebook viewer: ``from rig.open3d_lite import o3d``.

``import open3d`` imports ``open3d.visualization.draw_plotly``, which imports plotly and dash, and
dash imports IPython: 0.9 of the 1.5 s that ``import open3d`` takes on a 2-core machine, paid by
every process that ray-casts, meshes or reads a point cloud (isl-org/Open3D#7065 asks for it to
be optional). Nothing here draws with plotly, so that module is stood in for, before open3d is
imported, by one whose functions load the real module when first called; any other name asked of
it loads it too, so the stand-in can only cost time, never a function.
"""

from __future__ import annotations

import importlib
import importlib.util
import sys
import types
from collections.abc import Callable
from pathlib import Path
from typing import Any

_VIEWER = "open3d.visualization.draw_plotly"
#: What open3d.visualization imports from the viewer (open3d 0.19-0.20).
_VIEWER_NAMES = ("get_plotly_fig", "draw_plotly", "draw_plotly_server")


class _DeferredViewer(types.ModuleType):
    """Stands in for the viewer module; a name it does not hold loads the real one."""

    def __getattr__(self, name: str) -> Any:
        if name.startswith("__"):  # the import system's probes (__path__, ...) must not load it
            raise AttributeError(name)
        return getattr(_real_viewer(), name)


def _real_viewer() -> types.ModuleType:
    """The real viewer module, loaded from its file on first use (once)."""
    module = sys.modules.get(_VIEWER)
    if module is not None and not isinstance(module, _DeferredViewer):
        return module
    package = importlib.import_module("open3d.visualization")
    spec = importlib.util.spec_from_file_location(_VIEWER, Path(package.__file__).with_name("draw_plotly.py"))
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    sys.modules[_VIEWER] = module
    spec.loader.exec_module(module)
    return module


def _forwarded(name: str) -> Callable[..., Any]:
    def call(*args: Any, **kwargs: Any) -> Any:
        return getattr(_real_viewer(), name)(*args, **kwargs)

    call.__name__ = name
    return call


def _stand_in_for_the_viewer() -> None:
    """Put the stand-in in place, unless open3d is already imported (or absent)."""
    if "open3d" in sys.modules or _VIEWER in sys.modules or importlib.util.find_spec("open3d") is None:
        return
    viewer = _DeferredViewer(_VIEWER)
    for name in _VIEWER_NAMES:
        setattr(viewer, name, _forwarded(name))
    sys.modules[_VIEWER] = viewer


_stand_in_for_the_viewer()
import open3d as o3d  # noqa: E402  (after the stand-in)

__all__ = ["o3d"]
