"""A headless Chromium, driven through its DevTools protocol, to load a viewer page and take its picture.

Only what ``vfdsl view --screenshot`` and the tests need: start Chromium (``chromium``, ``chromium-browser``,
``google-chrome`` or ``$VFDSL_CHROMIUM``) with a private profile in a temporary folder, open one page, evaluate
JavaScript in it, capture a PNG, and stop the browser (its process group) on exit. WebGL runs on Chromium's
software renderer (SwiftShader), so no GPU or display is needed.
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
from pathlib import Path

from vfdsl.errors import VfError

CANDIDATES = ("chromium", "chromium-browser", "google-chrome", "google-chrome-stable")


def find_chromium() -> str | None:
    """The path of a Chromium-like browser, or None."""
    given = os.environ.get("VFDSL_CHROMIUM")
    if given:
        return shutil.which(given) or (given if Path(given).is_file() else None)
    for name in CANDIDATES:
        path = shutil.which(name)
        if path:
            return path
    return None


def chromium() -> str:
    """The path of a Chromium-like browser; VfError, saying how to get one, when there is none."""
    path = find_chromium()
    if path is None:
        raise VfError("no Chromium found for the screenshot",
                      hint="install it (Debian: apt-get install chromium) or set VFDSL_CHROMIUM")
    return path


class Browser:
    """One headless Chromium with one page. Use as a context manager. Whatever fails, once started, the
    browser is stopped and its profile removed: on leaving the context, or when entering it fails. What the
    browser does wrong (it exits, does not answer in ``timeout`` s, drops the connection) is a VfError."""

    def __init__(self, width: int = 1280, height: int = 800, timeout: float = 20.0):
        self.width, self.height, self.timeout = width, height, timeout
        self._profile: str | None = None
        self._process: subprocess.Popen | None = None
        self._socket = None
        self._ids = itertools.count(1)

    # ----------------------------------------------------------------------------------- lifecycle
    def __enter__(self) -> "Browser":
        executable = chromium()
        self._profile = tempfile.mkdtemp(prefix="vfdsl-chromium-")
        try:
            self._start(executable)
        except BaseException as err:
            self.close()
            if isinstance(err, Exception) and not isinstance(err, VfError):   # not executable, a bad reply, ...
                raise VfError(f"Chromium ({executable}) did not start: {type(err).__name__}: {err}") from None
            raise
        return self

    def _start(self, executable: str) -> None:
        args = [executable, "--headless=new", "--no-sandbox", "--disable-gpu-sandbox", "--no-first-run",
                "--no-default-browser-check", "--disable-extensions", "--disable-dev-shm-usage",
                "--use-angle=swiftshader", "--enable-unsafe-swiftshader", "--ignore-gpu-blocklist",
                "--remote-debugging-address=127.0.0.1", "--remote-debugging-port=0",
                f"--user-data-dir={self._profile}", f"--window-size={self.width},{self.height}", "about:blank"]
        self._process = subprocess.Popen(args, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
                                         start_new_session=True)
        port = self._devtools_port()
        request = urllib.request.Request(f"http://127.0.0.1:{port}/json/new?about:blank", method="PUT")
        with urllib.request.urlopen(request, timeout=self.timeout) as reply:
            target = json.load(reply)
        from websockets.sync.client import connect
        self._socket = connect(target["webSocketDebuggerUrl"], max_size=None, open_timeout=self.timeout)
        self.call("Page.enable")
        self.call("Runtime.enable")
        self.call("Emulation.setDeviceMetricsOverride", width=self.width, height=self.height,
                  deviceScaleFactor=1, mobile=False)

    def __exit__(self, *exc) -> None:
        self.close()

    def close(self) -> None:
        if self._socket is not None:
            try:
                self._socket.close()
            except Exception:
                pass
            self._socket = None
        if self._process is not None:       # its whole group: helpers can outlive the main process
            for sig in (signal.SIGTERM, signal.SIGKILL):
                try:
                    os.killpg(self._process.pid, sig)
                except ProcessLookupError:
                    break
                try:
                    self._process.wait(timeout=5)
                except subprocess.TimeoutExpired:
                    pass
        self._process = None
        if self._profile is not None:
            shutil.rmtree(self._profile, ignore_errors=True)
            self._profile = None

    def _devtools_port(self) -> int:
        marker = Path(self._profile) / "DevToolsActivePort"
        deadline = time.monotonic() + self.timeout
        while time.monotonic() < deadline:
            if self._process.poll() is not None:
                raise VfError(f"Chromium exited with status {self._process.returncode} before it opened its "
                              "DevTools port")
            if marker.exists():
                text = marker.read_text().split()
                if text and text[0].isdigit():                  # else: still being written
                    return int(text[0])
            time.sleep(0.05)
        raise VfError(f"Chromium did not open its DevTools port within {self.timeout:g} s")

    # -------------------------------------------------------------------------------------- protocol
    def call(self, method: str, **params):
        """Send one DevTools command and return its result (events that arrive meanwhile are dropped)."""
        from websockets.exceptions import ConnectionClosed
        ident = next(self._ids)
        deadline = time.monotonic() + self.timeout
        try:
            self._socket.send(json.dumps({"id": ident, "method": method, "params": params}))
            while True:
                message = json.loads(self._socket.recv(timeout=max(0.01, deadline - time.monotonic())))
                if message.get("id") == ident:
                    break
        except TimeoutError:
            raise VfError(f"Chromium did not answer {method} within {self.timeout:g} s") from None
        except (ConnectionClosed, OSError) as err:
            raise VfError(f"Chromium dropped its connection during {method}: {err}") from None
        if "error" in message:
            raise VfError(f"Chromium: {method} failed: {message['error'].get('message')}")
        return message.get("result", {})

    def open(self, url: str) -> None:
        self.call("Page.navigate", url=url)

    def evaluate(self, expression: str):
        result = self.call("Runtime.evaluate", expression=expression, returnByValue=True)
        return result.get("result", {}).get("value")

    def screenshot(self) -> bytes:
        """The page as PNG bytes."""
        return base64.b64decode(self.call("Page.captureScreenshot", format="png")["data"])
