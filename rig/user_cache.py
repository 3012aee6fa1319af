"""The project's cache folder on the user's machine: built extensions, downloaded weights."""

from __future__ import annotations

import os
from pathlib import Path


def cache_dir() -> Path:
    """``$LTS_CACHE_DIR``, else ``~/.cache/lidar-ts``."""
    return Path(os.environ.get("LTS_CACHE_DIR", Path.home() / ".cache" / "lidar-ts"))
