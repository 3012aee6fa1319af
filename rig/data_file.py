"""Reading a YAML or JSON file with one-line errors that name the file (and the line)."""

from __future__ import annotations

import json
from collections.abc import Sequence
from pathlib import Path
from typing import Any, Literal

import numpy as np
import yaml

from rig.errors import InputError


def load_data_file(path: str | Path, fmt: Literal["YAML", "JSON"], what: str) -> Any:
    """The parsed content of the YAML or JSON file ``path`` (any type: callers check its shape).

    Raises :class:`InputError` naming the file: ``cannot read WHAT (reason)`` when it cannot be
    read, ``not a text file (expected FMT)``, or ``not valid FMT (problem)`` with the line of the
    problem.
    """
    path = Path(path)
    try:
        text = path.read_text()
    except OSError as exc:
        raise InputError(f"cannot read {what} ({exc.strerror})", path=path) from None
    except UnicodeDecodeError:
        raise InputError(f"not a text file (expected {fmt})", path=path) from None
    try:
        return json.loads(text) if fmt == "JSON" else yaml.safe_load(text)
    except json.JSONDecodeError as exc:
        raise InputError(f"not valid JSON ({exc.msg})", path=path, line=exc.lineno) from None
    except yaml.MarkedYAMLError as exc:
        line = exc.problem_mark.line + 1 if exc.problem_mark is not None else None
        raise InputError(f"not valid YAML ({exc.problem or exc.context})", path=path, line=line) from None
    except yaml.YAMLError as exc:
        raise InputError(f"not valid YAML ({str(exc).splitlines()[0]})", path=path) from None


def matrix_field(document: Any, keys: Sequence[str], shape: tuple[int | None, ...], path: Path) -> np.ndarray:
    """The finite numbers at ``keys`` (nested mappings) of a parsed YAML or JSON ``document`` as a
    float64 array of ``shape`` (None: any length along that axis).

    Raises :class:`InputError` naming the file ``path`` and the field (the keys joined by dots).
    """
    node = document
    for key in keys:
        node = node.get(key) if isinstance(node, dict) else None
    try:
        matrix = None if node is None else np.asarray(node, dtype=np.float64)
    except (TypeError, ValueError):
        matrix = None
    fits = (
        matrix is not None
        and matrix.ndim == len(shape)
        and all(want is None or want == got for want, got in zip(shape, matrix.shape, strict=True))
        and bool(np.all(np.isfinite(matrix)))
    )
    if not fits:
        size = "x".join("N" if n is None else str(n) for n in shape)
        raise InputError(f"expected a {size} matrix of numbers", path=path, field=".".join(keys))
    return matrix  # type: ignore[return-value]
