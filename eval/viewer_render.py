"""Renders of the trained model at the viewpoints of ``lts view``'s browsers, made in one
background thread so that moving the camera never waits for the rasteriser."""

from __future__ import annotations

import threading
import time
from collections.abc import Callable

import numpy as np
import torch

from rig.cli_support import console
from slam_bridge.scene import Scene
from splat.model import TriangleModel

#: ``deliver(rgb)`` receives a ``(H, W, 3)`` uint8 render.
Deliver = Callable[[np.ndarray], None]


#: How long stopping waits for the render thread (s).
STOP_WAIT_S = 2.0


class ViewRenderer:
    """Renders ``model`` with ``scene``'s camera shrunk to at most ``max_width`` pixels wide.

    :meth:`request` keeps only each client's newest viewpoint; the thread renders what is
    pending, then rests ``min_interval_s`` so a dragged camera costs a few renders a second.
    """

    def __init__(
        self, model: TriangleModel, scene: Scene, max_width: int = 320, min_interval_s: float = 0.2
    ) -> None:
        camera = scene.camera
        width = min(camera.width, max_width)
        self.camera = camera.scaled(width, max(1, round(camera.height * width / camera.width)))
        self._model = model
        self._min_interval_s = min_interval_s
        self._pending: dict[int, tuple[np.ndarray, Deliver]] = {}
        self._lock = threading.Lock()
        self._wake = threading.Event()
        self._stopped = threading.Event()
        self._thread = threading.Thread(target=self._run, name="lts-view-render", daemon=True)
        self._thread.start()

    def render(self, T_world_cam: np.ndarray) -> np.ndarray:
        """``(H, W, 3)`` uint8 render of the model seen from ``T_world_cam`` ``(4, 4)``."""
        out = self._model.render_at(self.camera, T_world_cam)
        rgb = out.rgb.clamp(0, 1).mul(255).round().to(torch.uint8)
        return rgb.cpu().numpy()

    def request(self, client_id: int, T_world_cam: np.ndarray, deliver: Deliver) -> None:
        """Ask for a render from ``T_world_cam`` ``(4, 4)``, replacing the client's older request."""
        with self._lock:
            self._pending[client_id] = (np.array(T_world_cam, dtype=np.float64), deliver)
        self._wake.set()

    def forget(self, client_id: int) -> None:
        """Drop a disconnected client's pending request."""
        with self._lock:
            self._pending.pop(client_id, None)

    def stop(self) -> None:
        """Stop the thread: wait up to :data:`STOP_WAIT_S` for a render or a delivery in progress
        (a delivery to a browser that has gone can block; the thread is a daemon and ends with
        the process)."""
        self._stopped.set()
        self._wake.set()
        self._thread.join(timeout=STOP_WAIT_S)

    def _run(self) -> None:
        while not self._stopped.is_set():
            self._wake.wait()
            self._wake.clear()
            with self._lock:
                jobs, self._pending = list(self._pending.values()), {}
            for T_world_cam, deliver in jobs:
                if self._stopped.is_set():
                    return
                try:
                    deliver(self.render(T_world_cam))
                except Exception as exc:  # a failed render must not end the viewer's renders
                    console.print(f"lts view: render failed ({type(exc).__name__}: {exc})", markup=False)
            time.sleep(self._min_interval_s)
