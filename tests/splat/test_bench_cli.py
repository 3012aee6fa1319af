"""``lts bench raster``: the JSON contract, on a tiny scene."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

BIN = Path(sys.executable).parent


def test_bench_raster_json_has_the_contract_fields() -> None:
    cmd = [BIN / "lts", "bench", "raster", "--json", "-n", "200", "-n", "400", "--repeats", "1"]
    cmd += ["--width", "64", "--height", "48"]
    result = subprocess.run(cmd, capture_output=True, text=True, timeout=300)
    assert result.returncode == 0, result.stderr
    data = json.loads(result.stdout)
    rows = data["rows"]
    assert {(r["backend"], r["n_triangles"]) for r in rows} >= {
        ("reference", 200),
        ("cpu", 200),
        ("reference", 400),
        ("cpu", 400),
    }
    for row in rows:
        assert set(row) == {"backend", "n_triangles", "width", "height", "ms_fwd_bwd", "peak_mb"}
        assert (row["width"], row["height"]) == (64, 48)
        assert row["ms_fwd_bwd"] > 0 and row["peak_mb"] >= 0
    assert data["speedup_vs_reference"]["cpu"] > 0
    assert data["cpu_simd"]["float_lanes"] >= 1 and data["cpu_simd"]["instruction_set"]
    assert "cpu" in result.stderr  # the human-readable table goes to stderr
