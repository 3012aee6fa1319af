"""``--json`` keeps stdout for one JSON object, even when native code writes to descriptor 1."""

from __future__ import annotations

import json
import subprocess
import sys
import textwrap

SCRIPT = textwrap.dedent(
    """
    import os, sys
    import typer
    from rig.cli_support import emit_json, run_app

    app = typer.Typer()

    @app.command()
    def main(json_out: bool = typer.Option(False, "--json")) -> None:
        os.write(1, b"native library banner\\n")  # below sys.stdout, as OpenBLAS or pybullet do
        print("python print")
        if json_out:
            emit_json({"answer": 42})

    run_app(app, "demo")()
    """
)


def _run(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-c", SCRIPT, *args], capture_output=True, text=True, timeout=60)


def test_json_mode_sends_native_and_python_output_to_stderr() -> None:
    result = _run("--json")
    assert result.returncode == 0, result.stderr
    assert json.loads(result.stdout) == {"answer": 42}
    assert "native library banner" in result.stderr and "python print" in result.stderr


def test_without_json_stdout_is_untouched() -> None:
    result = _run()
    assert result.returncode == 0, result.stderr
    assert "native library banner" in result.stdout and "python print" in result.stdout
