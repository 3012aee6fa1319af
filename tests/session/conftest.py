"""A small synthetic virtual-rig scene (``SCENE/session.mcap``) for the recording tests."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from rig import CameraModel, Frame, ImuSample, Scan
from rig.session import SessionWriter

CAMERA = CameraModel("pinhole", 160, 120, [[150, 0, 80], [0, 150, 60], [0, 0, 1]], [])
RATES = {"image": 30.0, "points": 10.0, "imu": 200.0}


def room_scan(t_s: float, rng: np.random.Generator, n: int = 3000) -> Scan:
    """Rays from the origin to the walls of a 8 x 6 x 3 m room, with elevations within ±15 deg."""
    az = rng.uniform(-np.pi, np.pi, n)
    el = np.deg2rad(rng.uniform(-15, 15, n))
    d = np.stack([np.cos(el) * np.cos(az), np.cos(el) * np.sin(az), np.sin(el)], axis=1)
    half = np.array([4.0, 3.0, 1.5])
    with np.errstate(divide="ignore"):
        t = np.min(np.abs(half / d), axis=1)
    order = np.argsort(az)
    point_time = (np.arange(n) / n * 0.099).astype(np.float32)
    return Scan(
        (d * t[:, None])[order].astype(np.float32),
        point_time,
        rng.uniform(0, 255, n).astype(np.float32),
        t_host=int(1e9 + t_s * 1e9),
        t_device=None,
    )


def write_scene(scene: Path, seconds: float = 3.0) -> Path:
    scene.mkdir(parents=True, exist_ok=True)
    rng = np.random.default_rng(0)
    t0 = 1_000_000_000
    with SessionWriter(scene / "session.mcap", metadata={"sim": "synthetic test scene"}) as w:
        w.write_camera_info(CAMERA, t_host=t0)
        events = []
        for role, rate in RATES.items():
            events += [(round(i * 1e9 / rate), role) for i in range(int(seconds * rate))]
        for t_rel, role in sorted(events):
            t = t0 + t_rel
            if role == "image":
                image = np.full((120, 160, 3), (t_rel // 10_000_000) % 255, dtype=np.uint8)
                image[40:80, 60:100] = rng.integers(0, 255, (40, 40, 3), dtype=np.uint8)
                w.write_frame(Frame(image, t, None, "cam"))
            elif role == "points":
                w.write_scan(room_scan(t_rel / 1e9, rng))
            else:
                w.write_imu(ImuSample(np.array([0.0, 0.0, 0.1]), np.array([0.0, 0.0, 9.81]), t, None))
    return scene


@pytest.fixture(scope="session")
def scene_dir(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A 3 s synthetic scene (cheap: for the crash and signal tests)."""
    return write_scene(tmp_path_factory.mktemp("scene"))


@pytest.fixture(scope="session")
def virtual_rig_scene(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """``lts sim --quick`` output: 3 s of the room preset, 160x120 at 30 Hz, rosette LiDAR, IMU."""
    from rig.sim.config import SimConfig
    from rig.sim.simulate import simulate

    out = tmp_path_factory.mktemp("virtual_rig")
    simulate(SimConfig().quick(), out)
    return out


@pytest.fixture(scope="session")
def layout_bags(virtual_rig_scene: Path, tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    """``virtual_rig_scene`` written as others' bags, one per layout of ``bag_layouts.LAYOUTS``."""
    from bag_layouts import LAYOUTS, write_layout

    out = tmp_path_factory.mktemp("layouts")
    return {name: write_layout(virtual_rig_scene / "session.mcap", out, name) for name in LAYOUTS}
