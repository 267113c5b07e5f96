"""A headless Chromium page driven over the DevTools protocol, for the browser tests.

Launch flags as tests/export/test_cesium.py (SwiftShader WebGL, no sandbox, offline:
every URL is on 127.0.0.1). The page records console errors, uncaught exceptions and
failed requests (an HTTP status ≥ 400, or a load that failed and was not cancelled by the
page itself), evaluates JavaScript (awaiting promises), drags the mouse and takes
screenshots.
"""

from __future__ import annotations

import asyncio
import base64
import json
import os
import re
import shutil
import subprocess
import time
import urllib.request
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
MODULES = ROOT / ".browser" / "node_modules"


def chromium_or_skip(*packages: str) -> str:
    """Chromium's path, or skip naming what is missing (`make browser` installs it)."""
    chromium = shutil.which("chromium") or shutil.which("chromium-browser")
    if chromium is None:
        pytest.skip("Chromium is not installed (Debian: apt-get install chromium; "
                    "or `make browser`)")
    modules = Path(os.environ.get("GEOTERRAIN_WEB_ASSETS") or MODULES)
    for p in packages:
        if not (modules / p / "package.json").is_file():
            pytest.skip(f"the npm package {p} is not installed in {modules} (`make browser`)")
    return chromium


class Page:
    """One Chromium with one page; use as a context manager."""

    def __init__(self, chromium: str, profile: Path, size: tuple[int, int] = (1000, 700)):
        self.loop = asyncio.new_event_loop()
        self.proc = subprocess.Popen(
            [chromium, "--headless=new", "--no-sandbox", "--use-angle=swiftshader",
             "--enable-unsafe-swiftshader", "--ignore-gpu-blocklist",
             f"--window-size={size[0]},{size[1]}", "--remote-debugging-port=0",
             f"--user-data-dir={profile}", "about:blank"],
            stderr=subprocess.PIPE, text=True)
        try:
            self._connect()
        except BaseException:
            self.proc.kill()
            self.proc.wait()
            raise

    def _connect(self) -> None:
        port, t0 = None, time.time()
        while port is None and time.time() - t0 < 60:
            m = re.search(r"DevTools listening on ws://127.0.0.1:(\d+)/",
                          self.proc.stderr.readline())
            port = m and int(m.group(1))
        assert port, "Chromium did not open its DevTools port"
        pages = json.loads(urllib.request.urlopen(f"http://127.0.0.1:{port}/json/list").read())
        url = next(p["webSocketDebuggerUrl"] for p in pages if p["type"] == "page")
        from tornado.websocket import websocket_connect

        async def connect():
            return await websocket_connect(url, max_message_size=1 << 28)

        self.ws = self.loop.run_until_complete(asyncio.wait_for(connect(), 60))
        self.ids = iter(range(1, 1 << 30))
        self.console: list[str] = []  # every console line
        self.errors: list[str] = []  # console errors and uncaught exceptions
        self.failed: list[str] = []  # failed requests
        self.requests: list[str] = []
        self._ids: dict[str, str] = {}
        for m in ("Runtime.enable", "Log.enable", "Page.enable", "Network.enable"):
            self.call(m)

    # ------------------------------------------------------------------ protocol
    def _event(self, msg: dict) -> None:
        m, p = msg.get("method"), msg.get("params", {})
        if m == "Runtime.consoleAPICalled":
            line = p["type"] + ": " + " ".join(
                str(a.get("value", a.get("description", ""))) for a in p["args"])
            self.console.append(line)
            # CesiumJS reports a tile it could not load with console.log
            if p["type"] in ("error", "assert") or "An error occurred" in line \
                    or "Failed to obtain" in line:
                self.errors.append(line)
        elif m == "Runtime.exceptionThrown":
            self.errors.append("exception: " + json.dumps(p)[:600])
        elif m == "Log.entryAdded" and p["entry"]["level"] == "error":
            self.errors.append("log: " + p["entry"].get("text", "") + " "
                               + p["entry"].get("url", ""))
        elif m == "Network.requestWillBeSent":
            self._ids[p["requestId"]] = p["request"]["url"]
            self.requests.append(p["request"]["url"])
        elif m == "Network.responseReceived" and p["response"]["status"] >= 400:
            self.failed.append(f"{p['response']['status']} {p['response']['url']}")
        elif m == "Network.loadingFailed" and not p.get("canceled"):
            self.failed.append(f"{p.get('errorText')} {self._ids.get(p['requestId'])}")

    async def _call(self, method: str, params: dict) -> dict:
        i = next(self.ids)
        await self.ws.write_message(json.dumps({"id": i, "method": method, "params": params}))
        while True:
            raw = await self.ws.read_message()
            if raw is None:
                raise RuntimeError("Chromium closed the DevTools connection")
            msg = json.loads(raw)
            if msg.get("id") == i:
                if "error" in msg:
                    raise RuntimeError(f"{method}: {msg['error']}")
                return msg.get("result", {})
            self._event(msg)

    def call(self, method: str, **params) -> dict:
        return self.loop.run_until_complete(asyncio.wait_for(self._call(method, params), 300))

    # ------------------------------------------------------------------ actions
    def open(self, url: str) -> None:
        self.call("Page.navigate", url=url)

    def eval(self, expr: str):
        """The value of JavaScript ``expr`` (a promise is awaited)."""
        r = self.call("Runtime.evaluate", expression=expr, awaitPromise=True,
                      returnByValue=True)
        if "exceptionDetails" in r:
            raise RuntimeError(f"{expr[:80]}: {json.dumps(r['exceptionDetails'])[:400]}")
        return r.get("result", {}).get("value")

    def wait(self, expr: str, timeout: float = 240.0, every: float = 0.5):
        """Poll ``expr`` until it is truthy; its value (fails after ``timeout`` s)."""
        t0 = time.time()
        while time.time() - t0 < timeout:
            v = self.eval(expr)
            if v:
                return v
            time.sleep(every)
        pytest.fail(f"{expr} not true after {timeout:.0f} s; errors {self.errors[-5:]}, "
                    f"failed {self.failed[-5:]}, console {self.console[-5:]}")

    def screenshot(self, path: Path) -> Path:
        png = self.call("Page.captureScreenshot", format="png")
        path.write_bytes(base64.b64decode(png["data"]))
        return path

    def drag(self, x0: float, y0: float, x1: float, y1: float, steps: int = 12,
             button: str = "left") -> None:
        """Press at (x0, y0), move to (x1, y1) in ``steps``, release."""
        self.call("Input.dispatchMouseEvent", type="mouseMoved", x=x0, y=y0)
        self.call("Input.dispatchMouseEvent", type="mousePressed", x=x0, y=y0, button=button,
                  buttons=1, clickCount=1)
        for k in range(1, steps + 1):
            x, y = x0 + (x1 - x0) * k / steps, y0 + (y1 - y0) * k / steps
            self.call("Input.dispatchMouseEvent", type="mouseMoved", x=x, y=y, button=button,
                      buttons=1)
            time.sleep(0.05)
        self.call("Input.dispatchMouseEvent", type="mouseReleased", x=x1, y=y1, button=button,
                  buttons=0, clickCount=1)

    def close(self) -> None:
        async def close_ws():  # tornado writes the close frame on the running loop
            self.ws.close()

        try:
            self.loop.run_until_complete(close_ws())
        finally:
            self.proc.kill()
            self.proc.wait()
            self.loop.close()

    def __enter__(self) -> Page:
        return self

    def __exit__(self, *exc) -> None:
        self.close()
