"""The report page in a real browser: headless Chromium opens index.html from file:// and
reports no failed request, no request leaving the page's folder, no console error, every
figure laid out with a visible size, and a screenshot that is not blank.

Chromium is driven through its DevTools protocol over a pipe (--remote-debugging-pipe:
JSON messages separated by NUL bytes on file descriptors 3 and 4), so no browser download
and no network port. It is the Debian package `chromium` (docs/development.md).
"""

from __future__ import annotations

import base64
import io
import json
import os
import select
import shutil
import subprocess
import time
from pathlib import Path

import numpy as np
import pytest
from PIL import Image

from tests.helpers.report import evaluate_csv

# Every test here is a long end-to-end run (make test-fast leaves them out).
pytestmark = pytest.mark.slow

CHROMIUM = shutil.which("chromium") or "/usr/bin/chromium"
FLAGS = ["--headless", "--no-sandbox", "--disable-gpu", "--disable-background-networking",
         "--disable-component-update", "--no-first-run", "--disable-sync",
         "--disable-default-apps", "--mute-audio", "--hide-scrollbars"]
# Only against a hang (a browser that never answers); nothing here measures speed.
PATIENCE_S = 120


def _high_fd(fd: int) -> int:
    import fcntl

    high = fcntl.fcntl(fd, fcntl.F_DUPFD, 10)
    os.close(fd)
    return high


class DevTools:
    """A Chromium process and its DevTools pipe."""

    def __init__(self, profile: Path):
        to_browser_r, self._w = os.pipe()
        self._r, from_browser_w = os.pipe()
        # Moved above 9 first: a pipe end that is itself fd 3 or 4 would be overwritten by
        # the other's redirection.
        to_browser_r, from_browser_w = (_high_fd(to_browser_r), _high_fd(from_browser_w))
        # The browser reads commands on fd 3 and writes on fd 4; bash puts the pipes there
        # (dash cannot redirect from descriptors above 9).
        script = f'exec "$0" "$@" 3<&{to_browser_r} 4>&{from_browser_w}'
        self.proc = subprocess.Popen(
            ["bash", "-c", script, CHROMIUM, *FLAGS, "--remote-debugging-pipe",
             f"--user-data-dir={profile}", "about:blank"],
            pass_fds=(to_browser_r, from_browser_w), stdout=subprocess.DEVNULL,
            stderr=subprocess.DEVNULL)
        os.close(to_browser_r)
        os.close(from_browser_w)
        self._buf = b""
        self._id = 0
        self.events: list[dict] = []

    def send(self, method: str, params: dict | None = None, session: str | None = None) -> dict:
        self._id += 1
        msg = {"id": self._id, "method": method, "params": params or {}}
        if session:
            msg["sessionId"] = session
        os.write(self._w, json.dumps(msg).encode() + b"\0")
        while True:
            reply = self._next()
            if reply.get("id") == self._id:
                if "error" in reply:
                    raise RuntimeError(f"{method}: {reply['error']}")
                return reply.get("result", {})
            self.events.append(reply)

    def wait_for(self, method: str) -> dict:
        for e in self.events:
            if e.get("method") == method:
                return e
        while True:
            e = self._next()
            self.events.append(e)
            if e.get("method") == method:
                return e

    def _next(self) -> dict:
        deadline = time.monotonic() + PATIENCE_S
        while b"\0" not in self._buf:
            left = deadline - time.monotonic()
            if left <= 0 or self.proc.poll() is not None:
                raise RuntimeError("chromium stopped answering on its DevTools pipe")
            ready, _, _ = select.select([self._r], [], [], min(left, 1.0))
            if ready:
                chunk = os.read(self._r, 1 << 20)
                if not chunk:
                    raise RuntimeError("chromium closed its DevTools pipe")
                self._buf += chunk
        msg, self._buf = self._buf.split(b"\0", 1)
        return json.loads(msg)

    def close(self):
        try:
            if self.proc.poll() is None:
                try:
                    self.send("Browser.close")
                except (RuntimeError, OSError):
                    pass
        finally:
            try:
                self.proc.wait(timeout=20)
            except subprocess.TimeoutExpired:
                self.proc.kill()
                self.proc.wait()
            os.close(self._w)
            os.close(self._r)


FIGURES_JS = """JSON.stringify(Array.from(document.querySelectorAll('figure.figure')).map(f => {
  const svg = f.querySelector('svg');
  const r = svg.getBoundingClientRect();
  const s = getComputedStyle(svg);
  return {id: f.id, width: r.width, height: r.height, display: s.display,
          visibility: s.visibility, opacity: s.opacity,
          texts: svg.querySelectorAll('text').length};
}))"""


def require_browser(path: str) -> None:
    """A missing browser fails the test in one line saying how to get it (pytest prints
    no traceback for it): the suite's set-up, `make install`, installs it where it can."""
    if not os.access(path, os.X_OK):
        pytest.fail(f"{path} not found: the browser test needs Chromium, which `make install` "
                    "installs as root on Debian/Ubuntu (else: apt-get install -y chromium, or "
                    "your system's chromium package); see docs/development.md", pytrace=False)


def test_a_missing_browser_is_one_clear_failure(tmp_path):
    with pytest.raises(pytest.fail.Exception) as info:
        require_browser(str(tmp_path / "chromium"))
    assert info.value.pytrace is False  # reported as its message alone
    message = str(info.value)
    assert "\n" not in message
    assert message.startswith(f"{tmp_path / 'chromium'} not found: the browser test needs Chromium")


def test_page_in_headless_chromium(tmp_path, cli):
    require_browser(CHROMIUM)
    a = evaluate_csv(tmp_path / "a.csv", "kitti-c", "MonoViT")
    b = evaluate_csv(tmp_path / "b.csv", "kitti-c", "HR-Depth", tilt=0.1)
    out = tmp_path / "report"
    res = cli("report", a, b, "--out", out)
    assert res.exit_code == 0, res.output
    url = (out / "index.html").resolve().as_uri()

    browser = DevTools(tmp_path / "profile")
    try:
        target = browser.send("Target.createTarget", {"url": "about:blank"})["targetId"]
        session = browser.send("Target.attachToTarget", {"targetId": target, "flatten": True})["sessionId"]
        for domain in ("Page", "Runtime", "Network", "Log"):
            browser.send(f"{domain}.enable", session=session)
        browser.send("Emulation.setDeviceMetricsOverride",
                     {"width": 1280, "height": 900, "deviceScaleFactor": 1, "mobile": False},
                     session=session)
        browser.send("Page.navigate", {"url": url}, session=session)
        browser.wait_for("Page.loadEventFired")
        figures = json.loads(browser.send("Runtime.evaluate", {"expression": FIGURES_JS,
                                                                "returnByValue": True},
                                          session=session)["result"]["value"])
        width = browser.send("Runtime.evaluate", {"expression": "document.documentElement.scrollWidth",
                                                  "returnByValue": True}, session=session)["result"]["value"]
        shot = browser.send("Page.captureScreenshot", {"format": "png", "captureBeyondViewport": True},
                            session=session)["data"]
        events = list(browser.events)
    finally:
        browser.close()

    methods = [e.get("method") for e in events]
    requests = [e["params"]["request"]["url"] for e in events if e.get("method") == "Network.requestWillBeSent"]
    assert requests and requests[0] == url
    # Nothing but the page itself (and data: URLs) is requested: no CDN, font or favicon.
    assert all(r == url or r.startswith("data:") for r in requests), requests
    assert "Network.loadingFailed" not in methods, [e for e in events if e.get("method") == "Network.loadingFailed"]
    errors = [e for e in events if e.get("method") == "Runtime.exceptionThrown"
              or (e.get("method") == "Runtime.consoleAPICalled" and e["params"]["type"] in ("error", "assert"))
              or (e.get("method") == "Log.entryAdded" and e["params"]["entry"]["level"] == "error")]
    assert errors == []
    # Every figure is laid out, visible and sized to the page's column (not a 0x0 box).
    assert [f["id"] for f in figures] == ["fig-radar", "fig-ce", "fig-levels", "fig-summary"]
    for f in figures:
        assert f["display"] != "none" and f["visibility"] == "visible" and f["opacity"] == "1", f
        assert 300 < f["width"] <= 1280 and f["height"] > 200, f
        assert f["texts"] > 10, f  # the figure's words are text, not lost glyphs
    assert width <= 1280  # wide tables scroll inside their box; the page does not
    img = np.asarray(Image.open(io.BytesIO(base64.b64decode(shot))).convert("L"), dtype=np.float64)
    assert img.shape[1] == 1280 and img.shape[0] > 2000
    # Not blank: a real share of the page is ink, with the full range of grey.
    assert (img < 128).mean() > 0.01 and img.std() > 20
    # The first screenful shows the scores table: dark text and the shaded rows of yours.
    top = img[:900]
    assert (top < 100).mean() > 0.005
