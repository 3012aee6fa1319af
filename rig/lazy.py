"""Package exports that are imported on first use (PEP 562), so that importing a package — as
``lts --help`` does for every package — does not load torch or open3d."""

from __future__ import annotations

import importlib
from collections.abc import Callable
from typing import Any


def lazy_exports(package: str, exports: dict[str, str]) -> tuple[list[str], Callable[[str], Any]]:
    """``__all__`` and a module ``__getattr__`` that imports each name from its module when asked.

    Args:
        package: the package's ``__name__`` (for the error message).
        exports: public name → module that defines it, or ``module:name`` where the module names
            it otherwise.
    """

    def module_getattr(name: str) -> Any:
        if name not in exports:
            raise AttributeError(f"module {package!r} has no attribute {name!r}")
        module, _, defined_as = exports[name].partition(":")
        return getattr(importlib.import_module(module), defined_as or name)

    return sorted(exports), module_getattr
