"""Screenshots of a live page from headless Chromium over the DevTools protocol.

Chromium's one-shot ``--screenshot --virtual-time-budget`` can wait forever when a page keeps a
websocket busy (virtual time stands still while a fetch is pending), so the page is loaded in real
time and screenshotted repeatedly until the caller's test on the image holds or a deadline passes.
"""

from __future__ import annotations

import base64
import itertools
import json
import os
import shutil
import signal
import subprocess
import tempfile
import time
import urllib.request
from collections.abc import Callable
from pathlib import Path

import cv2
import numpy as np
from websockets.sync.client import ClientConnection, connect

CHROMIUM = shutil.which("chromium") or shutil.which("chromium-browser") or shutil.which("google-chrome")
#: Headless Chromium has no GPU here: WebGL runs on SwiftShader, which newer Chromium only enables
#: when asked (--enable-unsafe-swiftshader).
CHROMIUM_FLAGS = (
    "--headless",
    "--no-sandbox",
    "--disable-gpu",
    "--use-angle=swiftshader",
    "--enable-unsafe-swiftshader",
    "--hide-scrollbars",
    "--no-first-run",
    "--remote-debugging-port=0",
)


def _devtools_port(profile: Path, browser: subprocess.Popen, deadline: float) -> int:
    port_file = profile / "DevToolsActivePort"
    while time.monotonic() < deadline:
        if browser.poll() is not None:
            raise RuntimeError(f"Chromium exited with {browser.returncode}")
        if port_file.is_file() and port_file.read_text().strip():
            return int(port_file.read_text().splitlines()[0])
        time.sleep(0.2)
    raise TimeoutError("Chromium did not open its DevTools port")


def _page_socket_url(port: int, deadline: float) -> str:
    while time.monotonic() < deadline:
        with urllib.request.urlopen(f"http://127.0.0.1:{port}/json/list", timeout=5.0) as reply:
            pages = [t for t in json.load(reply) if t.get("type") == "page"]
        if pages:
            return pages[0]["webSocketDebuggerUrl"]
        time.sleep(0.2)
    raise TimeoutError("Chromium opened no page")


def _call(page: ClientConnection, message_id: int, method: str, deadline: float, **params) -> dict:
    """Send one DevTools command and return its result, skipping the events sent meanwhile."""
    page.send(json.dumps({"id": message_id, "method": method, "params": params}))
    while True:
        reply = json.loads(page.recv(timeout=max(deadline - time.monotonic(), 5.0)))
        if reply.get("id") == message_id:
            return reply["result"]


def screenshot_when(
    url: str,
    ready: Callable[[np.ndarray], bool],
    size: tuple[int, int] = (1280, 800),
    timeout_s: float = 180.0,
) -> np.ndarray:
    """Load ``url`` in headless Chromium and screenshot it every second until ``ready(image)``.

    Args:
        url: the page to load.
        ready: the test on a BGR screenshot (H, W, 3) uint8 that ends the wait.
        size: the window's (width, height) in pixels.
        timeout_s: how long to wait in all.

    Returns:
        The first screenshot that ``ready`` accepts, or the last one taken at the deadline
        (H, W, 3) uint8, BGR.
    """
    if CHROMIUM is None:
        raise RuntimeError("no Chromium on PATH")
    deadline = time.monotonic() + timeout_s
    # Killing the browser alone left its helper processes writing into the profile while it was
    # removed ("Directory not empty: 'Default'" in one full-suite run): the whole process group is
    # killed, and a helper that left the group cannot fail the test by writing a late file.
    with tempfile.TemporaryDirectory(prefix="chromium-", ignore_cleanup_errors=True) as profile:
        window = f"--window-size={size[0]},{size[1]}"
        browser = subprocess.Popen(
            [CHROMIUM, *CHROMIUM_FLAGS, window, f"--user-data-dir={profile}", url],
            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, start_new_session=True,
        )  # fmt: skip
        try:
            port = _devtools_port(Path(profile), browser, deadline)
            with connect(_page_socket_url(port, deadline), max_size=None, open_timeout=30) as page:
                ids = itertools.count(1)
                # The viewport the window size leaves is smaller than the window: set it exactly.
                viewport = {"width": size[0], "height": size[1], "deviceScaleFactor": 1, "mobile": False}
                _call(page, next(ids), "Emulation.setDeviceMetricsOverride", deadline, **viewport)
                for message_id in ids:
                    shot = _call(page, message_id, "Page.captureScreenshot", deadline)
                    png = np.frombuffer(base64.b64decode(shot["data"]), np.uint8)
                    image = cv2.imdecode(png, cv2.IMREAD_COLOR)
                    if ready(image) or time.monotonic() > deadline:
                        return image
                    time.sleep(1.0)
        finally:
            os.killpg(browser.pid, signal.SIGKILL)
            browser.wait()
