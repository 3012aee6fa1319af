"""open3d imported through rig.open3d_lite: no plotly or dash until its notebook viewer is used."""

import subprocess
import sys

import pytest

pytest.importorskip("open3d")


def _run(code: str) -> str:
    result = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert result.returncode == 0, result.stdout + result.stderr
    return result.stdout.strip()


def test_open3d_loads_without_its_notebook_viewer_until_it_is_used() -> None:
    code = (
        "import sys; from rig.open3d_lite import o3d;"
        "print(sorted(m for m in ('dash', 'plotly', 'IPython') if m in sys.modules));"
        "cloud = o3d.geometry.PointCloud(o3d.utility.Vector3dVector([[0.0, 0, 0], [1, 1, 1]]));"
        "figure = o3d.visualization.get_plotly_fig([cloud]);"
        "print(type(figure).__name__, len(figure.data), 'dash' in sys.modules)"
    )
    loaded, used = _run(code).splitlines()
    assert loaded == "[]"
    assert used == "Figure 1 True"  # the real viewer, loaded on its first call


def test_open3d_imported_before_is_left_as_it_is() -> None:
    code = (
        "import open3d, sys; from rig.open3d_lite import o3d;"
        "print(o3d is open3d, type(sys.modules['open3d.visualization.draw_plotly']).__name__)"
    )
    assert _run(code) == "True module"
