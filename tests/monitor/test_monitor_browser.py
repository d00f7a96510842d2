"""A real browser watches a dry run in real time: the traces move, and the page says when the session
stops (skipped without chromium)."""

from __future__ import annotations

import json
import re
import signal
import time
from pathlib import Path
from typing import Any

import pytest

from ..session.conftest import cli
from .cdp import CHROMIUM, Browser

pytestmark = [
    pytest.mark.browser,
    pytest.mark.skipif(CHROMIUM is None, reason="chromium is not on PATH (CI installs it with apt)"),
]

STATE = "JSON.stringify(Object.assign({}, document.body.dataset))"
# pixels of the measured-angle colour (#1f6fd1) on the first traces canvas: the trace is drawn
ANGLE_PIXELS = """(() => {
  const c = document.querySelector("canvas.traces");
  if (!c) return 0;
  const d = c.getContext("2d").getImageData(0, 0, c.width, c.height).data;
  let n = 0;
  for (let i = 0; i < d.length; i += 4) if (d[i] < 60 && d[i + 1] > 90 && d[i + 1] < 130 && d[i + 2] > 190) n++;
  return n;
})()"""


def wait_until(condition: Any, timeout: float, what: str) -> Any:
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        value = condition()
        if value:
            return value
        time.sleep(0.25)
    raise AssertionError(f"timed out waiting for {what}")


def test_the_page_shows_the_motion_live_and_the_stop(tmp_path: Path) -> None:
    log = tmp_path / "session.err"
    session = cli(
        "knee_phase1.yaml",
        "--dry-run",
        "--realtime",
        "--only",
        "12",
        "--session",
        str(tmp_path / "s"),
        "--monitor",
        "127.0.0.1:0",
        log=log,
    )
    browser = Browser(tmp_path / "profile")
    try:
        url = wait_until(
            lambda: (
                (m := re.search(r"monitor: (http://127\.0\.0\.1:\d+/\?token=[\w-]+)", log.read_text()))
                and m.group(1)
            ),
            60,
            "the monitor's URL on the terminal",
        )
        browser.open(url)

        def state() -> dict[str, str]:
            return json.loads(browser.evaluate(STATE) or "{}")

        first = wait_until(lambda: (s := state()) and int(s.get("points", 0)) > 20 and s, 60, "samples")
        time.sleep(3.0)
        later = state()
        assert later["state"] == "live"
        assert float(later["lastT"]) - float(first["lastT"]) > 2.0  # 3 s later the traces moved on ~3 s
        assert int(later["frames"]) > int(first["frames"])  # and were redrawn
        assert later["step"]  # the current step is shown
        assert browser.evaluate(ANGLE_PIXELS) > 200  # the measured angle is drawn
        browser.screenshot(tmp_path / "monitor.png")

        session.send_signal(signal.SIGINT)
        assert session.wait(timeout=60) == 130
        ended = wait_until(lambda: (s := state()).get("state") == "ended" and s, 10, "the end on the page")
        assert ended["state"] == "ended"
        banner = browser.evaluate("document.getElementById('banner').textContent")
        assert "interrupted" in banner and "--resume" in banner
    finally:
        browser.close()
        if session.poll() is None:
            session.proc.kill()
            session.wait(timeout=10)
