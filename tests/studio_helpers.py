"""Running a studio in a child process for the tests (the real CLI, a real socket)."""
from __future__ import annotations

import contextlib
import os
import re
import signal
import subprocess
import sys
import threading
import time
import urllib.error
import urllib.request
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
PHONE = ROOT / "assets" / "scenes" / "phone.toml"
#: Longest wait for a studio's first compile (s): generous for a busy machine.
READY_TIMEOUT = 120.0


@contextlib.contextmanager
def studio_page(source, ready: str, height: int = 980):
    """A studio on ``source`` and a headless Chromium page on it, once ``ready`` (a JS condition) holds.

    The page carries ``studio`` (the :class:`StudioProcess`), ``js_errors`` (the page's uncaught errors)
    and ``browser``; both are closed on exit.
    """
    sync_playwright, chromium = require_chromium()
    studio = StudioProcess(source)
    try:
        with sync_playwright() as p:
            browser = p.chromium.launch(executable_path=chromium, args=["--autoplay-policy=no-user-gesture-required"])
            try:
                # the page's Content-Security-Policy forbids eval; Playwright's waiting helpers need it
                pg = browser.new_page(viewport={"width": 1500, "height": height}, bypass_csp=True)
                errors: list = []
                pg.on("pageerror", lambda e: errors.append(str(e)))
                pg.goto(studio.url)
                pg.wait_for_function(ready, timeout=60000)
                pg.studio, pg.js_errors, pg.browser = studio, errors, browser
                yield pg
            finally:
                browser.close()
    finally:
        studio.stop()


def require_chromium():
    """``(sync_playwright, chromium path)`` for a browser test module; the module is skipped without them
    (Debian's ``chromium`` and the playwright package), and fails on CI, which must have them."""
    import shutil

    import pytest
    pytest.importorskip("starlette")
    chromium = shutil.which("chromium") or "/usr/bin/chromium"
    try:
        from playwright.sync_api import sync_playwright
    except ImportError:                                       # pragma: no cover
        sync_playwright = None
    if sync_playwright is None or not Path(chromium).is_file():
        if os.environ.get("CI"):
            pytest.fail("CI needs chromium (scripts/install-system-deps.sh --with-studio) and playwright (pip)",
                        pytrace=False)
        pytest.skip("needs Debian's chromium and the playwright package", allow_module_level=True)
    return sync_playwright, chromium


class StudioProcess:
    """``shapedisplay studio SOURCE --no-browser --port 0`` in a child process."""

    def __init__(self, source, *args, timeout: float = 60.0):
        cmd = [sys.executable, "-m", "shapedisplay", "studio", str(source), "--no-browser", "--port", "0", *args]
        self.proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                                     cwd=ROOT, env={**os.environ, "PYTHONUNBUFFERED": "1"})
        self.lines: list[str] = []
        self._url = threading.Event()
        self.url = None
        threading.Thread(target=self._read, daemon=True).start()
        end = time.monotonic() + timeout
        while not self._url.wait(0.1):
            if self.proc.poll() is not None or time.monotonic() > end:
                break
        if self.url is None:
            self.stop()
            raise RuntimeError(f"studio printed no URL in {timeout} s: {self.lines} {self.proc.stderr.read()}")
        m = re.match(r"http://([^/]+)/\?token=(\S+)", self.url)
        self.host, self.token = m.group(1), m.group(2)
        self.base = f"http://{self.host}"
        # the socket listens at once; requests are answered after the first compile: wait for it here,
        # not in each test
        self.wait_state(lambda st: st["generation"] >= 1, timeout=READY_TIMEOUT)

    def _read(self):
        for line in self.proc.stdout:
            self.lines.append(line)
            m = re.search(r"http://127\.0\.0\.1:\d+/\?token=\S+", line)
            if m and self.url is None:
                self.url = m.group(0)
                self._url.set()

    def get(self, path: str, token: bool = True, headers: dict | None = None, method: str = "GET",
            data: bytes | None = None):
        """(status, body bytes) of a request to the studio."""
        sep = "&" if "?" in path else "?"
        url = self.base + path + (f"{sep}token={self.token}" if token else "")
        req = urllib.request.Request(url, headers=headers or {}, method=method, data=data)
        try:
            with urllib.request.urlopen(req, timeout=30) as r:
                return r.status, r.read()
        except urllib.error.HTTPError as exc:
            return exc.code, exc.read()

    def wait_state(self, predicate, timeout: float = 30.0) -> dict:
        """Poll /api/state until ``predicate(state)`` holds."""
        import json
        end = time.monotonic() + timeout
        while True:
            try:
                status, body = self.get("/api/state")
            except OSError:                     # not answering yet (a timeout while it compiles)
                status, body = 0, b""
            if self.proc.poll() is not None:
                raise AssertionError(f"the studio exited ({self.proc.returncode}): {self.proc.stderr.read()}")
            if status == 200:
                st = json.loads(body)
                if predicate(st):
                    return st
            if time.monotonic() > end:
                raise AssertionError(f"studio state never matched: {st if status == 200 else status}")
            time.sleep(0.05)

    def stop(self) -> int:
        if self.proc.poll() is None:
            self.proc.send_signal(signal.SIGINT)
            try:
                self.proc.wait(20)
            except subprocess.TimeoutExpired:
                self.proc.kill()
                self.proc.wait()
        return self.proc.returncode
