"""Running a console-script entry point (``rig.cli.main``, ``lts.cli.main``) inside a test."""

from __future__ import annotations

import sys
from collections.abc import Callable

import pytest


def run_console_script(
    main: Callable[[], None], args: list, monkeypatch: pytest.MonkeyPatch, capsys
) -> tuple[int, str, str]:
    """Run ``main`` with ``args`` in this process, as the installed entry point does (one-line
    errors, exit statuses); returns ``(exit status, stdout, stderr)``."""
    monkeypatch.setattr(sys, "argv", ["prog", *map(str, args)])
    monkeypatch.setenv("COLUMNS", "400")  # one logical line is one printed line
    code = 0
    try:
        main()
    except SystemExit as exc:
        code = exc.code if isinstance(exc.code, int) else 1
    out, err = capsys.readouterr()
    return code, out, err
