"""A headless Chromium page driven over the DevTools protocol, for the viewer's browser
test (tests/test_viz.py) and the screenshots in docs/viewer.md (:func:`capture`).

Headless Chromium has no GPU here; SwiftShader renders WebGL in software. websockets and
Pillow come with viser, so this module, like the viewer, needs viser installed.
"""

from __future__ import annotations

import base64
import io
import json
import shutil
import subprocess
import tempfile
import time
import urllib.request
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
from PIL import Image
from websockets.sync.client import connect

from viz.app import serve

WIDTH, HEIGHT = 1280, 800
"""Default page size [px]."""
CHROMIUM_NAMES = ("chromium", "chromium-browser", "google-chrome", "google-chrome-stable")
CHROMIUM_FLAGS = (
    "--headless", "--no-sandbox", "--disable-gpu", "--use-angle=swiftshader",
    "--enable-unsafe-swiftshader", "--disable-quic", "--no-first-run",
    "--disable-background-networking", "--disable-component-update", "--disable-sync",
    "--disable-dev-shm-usage", "--hide-scrollbars", "--mute-audio",
)


def wait_for(predicate: Callable[[], Any], timeout: float, what: str, interval: float = 0.25
             ) -> Any:
    """The first truthy (non-empty) value of ``predicate()``, polled every ``interval`` s;
    AssertionError naming ``what`` after ``timeout`` s."""
    deadline = time.monotonic() + timeout
    while True:
        value = predicate()
        if value is not None and value is not False and not (isinstance(value, list)
                                                             and not value):
            return value
        if time.monotonic() > deadline:
            raise AssertionError(f"timed out after {timeout:.0f} s waiting for {what}")
        time.sleep(interval)


def find_chromium() -> str | None:
    """Path of an installed Chromium or Chrome, or None."""
    return next((p for name in CHROMIUM_NAMES if (p := shutil.which(name))), None)


class Chromium:
    """A headless Chromium page driven over the DevTools protocol (websockets, which
    viser already depends on)."""

    def __init__(self, executable: str, width: int = WIDTH, height: int = HEIGHT) -> None:
        self._profile = tempfile.mkdtemp(prefix="viz-chromium-")
        self.proc = subprocess.Popen(
            [executable, *CHROMIUM_FLAGS, f"--window-size={width},{height}",
             f"--user-data-dir={self._profile}",
             "--remote-debugging-port=0", "about:blank"],
            stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
        port_file = Path(self._profile) / "DevToolsActivePort"

        def devtools_port() -> int | None:
            if self.proc.poll() is not None:
                err = self.proc.stderr.read().decode(errors="replace") if self.proc.stderr else ""
                raise AssertionError(f"chromium exited with {self.proc.returncode}: {err[-2000:]}")
            text = port_file.read_text() if port_file.exists() else ""
            return int(text.split()[0]) if text.strip() else None

        port = wait_for(devtools_port, 20.0, "chromium's DevTools port")
        with urllib.request.urlopen(f"http://127.0.0.1:{port}/json/list", timeout=10) as r:
            targets = json.load(r)
        page = next(t for t in targets if t["type"] == "page")
        self._ws = connect(page["webSocketDebuggerUrl"], max_size=None, open_timeout=10)
        self._id = 0
        self.call("Page.enable")
        self.call("Emulation.setDeviceMetricsOverride", width=width, height=height,
                  deviceScaleFactor=1, mobile=False)

    def call(self, method: str, **params: Any) -> dict[str, Any]:
        """Send one DevTools command and return its result (events are skipped)."""
        self._id += 1
        self._ws.send(json.dumps({"id": self._id, "method": method, "params": params}))
        while True:
            msg = json.loads(self._ws.recv(timeout=30))
            if msg.get("id") == self._id:
                if "error" in msg:
                    raise AssertionError(f"DevTools {method}: {msg['error']}")
                return msg["result"]

    def screenshot(self) -> np.ndarray:
        """The page as an (H, W, 3) uint8 RGB array."""
        data = base64.b64decode(self.call("Page.captureScreenshot", format="png")["data"])
        return np.asarray(Image.open(io.BytesIO(data)).convert("RGB"))

    def evaluate(self, expression: str) -> Any:
        return self.call("Runtime.evaluate", expression=expression,
                         returnByValue=True)["result"].get("value")

    def close(self) -> None:
        try:
            self._ws.close()
        finally:
            self.proc.terminate()
            try:
                self.proc.wait(timeout=10)
            except subprocess.TimeoutExpired:
                self.proc.kill()
            shutil.rmtree(self._profile, ignore_errors=True)


NOTICE_JS = ("(() => { const n = document.querySelectorAll('.mantine-Notification-root');"
             " n.forEach(e => e.remove()); return n.length; })()")
"""Remove the page's notifications; their count."""


def page_text(page: Chromium) -> str:
    """Everything the page shows as text (viser's panel: labels, markdown, dropdowns)."""
    return str(page.evaluate("document.body.innerText") or "")


def open_view(page: Chromium, viewer: Any, timeout: float = 30.0) -> Any:
    """Load ``viewer``'s page (a ``viz.app.Viewer``) and wait until the browser has taken
    its initial camera; the client's camera handle."""
    page.call("Page.navigate", url=viewer.url)
    server = viewer.server
    clients = wait_for(lambda: list(server.get_clients().values()), timeout,
                       "the page to connect")
    camera = clients[0].camera
    initial = np.asarray(server.initial_camera.position)
    wait_for(lambda: camera.image_width > 0
             and np.allclose(camera.position, initial, atol=1e-3),
             timeout, "the browser's camera to take the viewer's initial pose")
    return camera


def settled(page: Chromium, timeout: float = 40.0, interval: float = 1.0) -> np.ndarray:
    """A screenshot once two in a row, ``interval`` s apart, are the same (the scene's
    nodes arrive one by one)."""
    last: list[np.ndarray] = [page.screenshot()]

    def same() -> np.ndarray | None:
        img = page.screenshot()
        prev, last[0] = last[0], img
        return img if np.array_equal(img, prev) else None

    return wait_for(same, timeout, "the page to stop changing", interval=interval)


def capture(run_dir: str | Path, out: str | Path, *, colour: str | None = None,
            mocap: bool = False, time_fraction: float = 0.5, width: int = WIDTH,
            height: int = HEIGHT) -> Path:
    """Screenshot of the view of ``run_dir`` in headless Chromium, written to ``out`` as a
    256-colour PNG (small enough for the docs): the path coloured by ``colour`` (a Path
    colour entry, ``viz.recorded.RESIDUAL_CHOICES``' label) if given, the raw motion
    capture if ``mocap``, the vehicle at ``time_fraction`` of the flight."""
    executable = find_chromium()
    if executable is None:
        raise RuntimeError("no Chromium found (Debian: apt-get install -y chromium)")
    viewer = serve(run_dir, port=0)
    page = Chromium(executable, width, height)
    try:
        if colour is not None:
            if viewer.colour_dropdown is None:
                raise ValueError(f"{run_dir}: no residual table to colour the path by")
            viewer.colour_dropdown.value = colour
        if mocap and viewer.mocap_checkbox is not None:
            viewer.mocap_checkbox.value = True
        f = viewer.flight
        if f is not None:
            viewer.time_slider.value = float(f.t[0] + time_fraction * f.duration)
        open_view(page, viewer)
        # SwiftShader makes viser warn of software WebGL; the warning is not the view's.
        wait_for(lambda: page.evaluate(NOTICE_JS) is not None, 10.0, "the page's notices")
        img = settled(page)
    finally:
        page.close()
        viewer.stop()
    out = Path(out)
    out.parent.mkdir(parents=True, exist_ok=True)
    Image.fromarray(img).quantize(256).save(out, optimize=True)
    return out
