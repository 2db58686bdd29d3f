"""The HTML report opens in a real browser: no console error, every picture loads.

A report (synthetic SceneResults of every verdict, through
softras.verification.report.write_report) and a merged report (4 synthetic
shards through ``softras conformance --merge``) are opened in headless
Chromium, driven over the DevTools protocol on a pipe
(``--remote-debugging-pipe``: file descriptors 3 and 4, NUL-separated JSON;
no websocket, no extra Python package). The page must load with no console
error or uncaught exception, no failed request and no error in the browser's
log (a missing picture is a ``net::ERR_FILE_NOT_FOUND`` there), every
``<img>`` must have decoded (``naturalWidth`` > 0) and exist on disk, and
every in-page link must name an element of the page.

Chromium is Debian's ``chromium`` (``scripts/install_test_tools.sh`` in the README's test
command installs it when missing);
``SOFTRAS_CHROMIUM`` names another binary. As with GL (tests/conftest.py), a
missing browser fails these tests unless ``SOFTRAS_ALLOW_NO_BROWSER=1``.
"""

from __future__ import annotations

import json
import os
import select
import shutil
import subprocess
import tempfile
import time
from pathlib import Path

import numpy as np
import pytest

from softras.cli import main
from softras.verification.conformance import CRASH, FAIL, FLAKY, NOT_SUPPORTED, PASS, TIMEOUT, WARN, SceneResult
from softras.verification.report import write_report

FLAGS = ["--headless", "--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
         "--disable-background-networking", "--disable-component-update", "--disable-sync",
         "--remote-debugging-pipe"]
TIMEOUT_S = 60.0
# What the page reports to the console once loaded: every picture and its decoded width, broken links.
PROBE = """JSON.stringify({
  images: Array.from(document.images).map(i => [i.getAttribute('src'), i.complete, i.naturalWidth]),
  brokenLinks: Array.from(document.querySelectorAll('a[href^="#"]'))
      .map(a => a.getAttribute('href').slice(1)).filter(id => !document.getElementById(id)),
  title: document.title})"""


def chromium() -> str:
    names = [os.environ["SOFTRAS_CHROMIUM"]] if os.environ.get("SOFTRAS_CHROMIUM") else \
        ["chromium", "chromium-browser", "google-chrome"]
    found = next((path for name in names if (path := shutil.which(name))), None)
    if found is None:
        message = "no Chromium (apt-get install chromium, or SOFTRAS_CHROMIUM=PATH)"
        if os.environ.get("SOFTRAS_ALLOW_NO_BROWSER") == "1":
            pytest.skip(message)
        pytest.fail(message + "; SOFTRAS_ALLOW_NO_BROWSER=1 skips the browser tests")
    return found


class Browser:
    """Headless Chromium over the DevTools protocol on a pipe."""

    def __init__(self, binary: str):
        self.profile = tempfile.mkdtemp(prefix="softras-chromium-")
        to_chrome_read, self.to_chrome = os.pipe()
        self.from_chrome, from_chrome_write = os.pipe()

        def plumbing():   # the child reads commands on fd 3 and writes answers on fd 4
            os.dup2(to_chrome_read, 3)
            os.dup2(from_chrome_write, 4)

        self.process = subprocess.Popen([binary, *FLAGS, f"--user-data-dir={self.profile}", "about:blank"],
                                        pass_fds=(3, 4), preexec_fn=plumbing, stdin=subprocess.DEVNULL,
                                        stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
        os.close(to_chrome_read)
        os.close(from_chrome_write)
        self.buffer = b""
        self.next_id = 0
        self.events: list[dict] = []

    def send(self, method: str, params: dict | None = None, session: str | None = None) -> dict:
        self.next_id += 1
        message = {"id": self.next_id, "method": method, "params": params or {}}
        if session:
            message["sessionId"] = session
        os.write(self.to_chrome, json.dumps(message).encode() + b"\0")
        return self.wait(lambda m: m.get("id") == self.next_id)

    def wait(self, done, timeout: float = TIMEOUT_S) -> dict:
        """Read messages (keeping the events) until ``done(message)``."""
        deadline = time.monotonic() + timeout
        while True:
            while b"\0" not in self.buffer:
                ready, _, _ = select.select([self.from_chrome], [], [], max(0.0, deadline - time.monotonic()))
                if not ready:
                    raise TimeoutError("Chromium did not answer in time")
                chunk = os.read(self.from_chrome, 1 << 16)
                if not chunk:
                    raise EOFError("Chromium closed the pipe: " + self.process.stderr.read().decode()[-2000:])
                self.buffer += chunk
            raw, self.buffer = self.buffer.split(b"\0", 1)
            message = json.loads(raw)
            if "error" in message:
                raise RuntimeError(f"DevTools: {message['error']}")
            if "method" in message:
                self.events.append(message)
            if done(message):
                return message

    def open(self, page: Path) -> dict:
        """Load ``page``; return the probe's answer and the problems the browser reported."""
        targets = self.send("Target.getTargets")["result"]["targetInfos"]
        target = next(t for t in targets if t["type"] == "page")
        session = self.send("Target.attachToTarget", {"targetId": target["targetId"], "flatten": True})
        session = session["result"]["sessionId"]
        for domain in ("Runtime", "Log", "Network", "Page"):
            self.send(f"{domain}.enable", session=session)
        self.send("Page.navigate", {"url": page.resolve().as_uri()}, session=session)
        self.wait(lambda m: m.get("method") == "Page.loadEventFired")
        answer = self.send("Runtime.evaluate", {"expression": PROBE, "returnByValue": True}, session=session)
        probe = json.loads(answer["result"]["result"]["value"])
        probe["problems"] = problems(self.events)
        return probe

    def close(self) -> None:
        try:
            self.send("Browser.close")
            self.process.wait(timeout=20)
        except (OSError, TimeoutError, EOFError, RuntimeError):
            self.process.kill()
            self.process.wait()
        finally:
            os.close(self.to_chrome)
            os.close(self.from_chrome)
            self.process.stderr.close()
            shutil.rmtree(self.profile, ignore_errors=True)


def problems(events: list[dict]) -> list[str]:
    """Console errors and warnings, uncaught exceptions, failed requests, errors in the browser's log."""
    found = []
    for event in events:
        method, params = event["method"], event.get("params", {})
        if method == "Runtime.consoleAPICalled" and params.get("type") in ("error", "warning", "assert"):
            found.append(f"console.{params['type']}: " + " ".join(str(arg.get("value", arg.get("description")))
                                                                for arg in params.get("args", [])))
        elif method == "Runtime.exceptionThrown":
            found.append("exception: " + params["exceptionDetails"].get("text", ""))
        elif method == "Log.entryAdded" and params["entry"]["level"] in ("error", "warning"):
            found.append(f"log {params['entry']['level']}: {params['entry']['text']} {params['entry'].get('url', '')}")
        elif method == "Network.loadingFailed":
            found.append(f"request failed: {params.get('errorText')}")
    return found


@pytest.fixture(scope="module")
def browser():
    instance = Browser(chromium())
    yield instance
    instance.close()


@pytest.fixture
def page(browser):
    """``page(index_html)`` -> the probe, in a fresh tab state (the events of earlier pages dropped)."""
    def load(index: Path) -> dict:
        browser.events.clear()
        return browser.open(index)
    return load


def picture(seed: int) -> np.ndarray:
    rng = np.random.default_rng(seed)
    image = rng.integers(0, 256, (12, 16, 4), dtype=np.uint8)
    image[..., 3] = 255
    return image


def every_verdict() -> list[SceneResult]:
    images = {key: picture(i) for i, key in enumerate(("soft", "gl", "diff", "where", "ssim", "flip", "ambiguity"))}
    attempt = {"attempt": 1, "verdict": FAIL, "reasons": ["first try differs"], "seconds": 0.1}
    results = []
    for verdict in (PASS, WARN, FAIL, NOT_SUPPORTED, CRASH, TIMEOUT, FLAKY):
        results.append(SceneResult(
            name=f"scene_{verdict}", path=f"scenes/scene_{verdict}.json", verdict=verdict,
            reasons=[] if verdict == PASS else [f"{verdict}: <why> & where (3, 4)"], description="a scene",
            tolerance={"threshold": 2, "max_bad_fraction": 0.001, "min_ssim": 0.99}, tolerance_source="defaults",
            figures={"ssim": 0.999, "max_diff": 3, "bad_pixels": 1, "flip_mean": 0.001}, seconds=0.5,
            images={} if verdict in (NOT_SUPPORTED, CRASH, TIMEOUT) else dict(images),
            attempts=[attempt, {**attempt, "attempt": 2, "verdict": PASS, "reasons": []}] if verdict == FLAKY
            else []))
    return results


def check_page(folder: Path, probe: dict, expected_images: int) -> None:
    assert probe["problems"] == []
    assert probe["title"] == "softras conformance"
    assert probe["brokenLinks"] == []
    assert len(probe["images"]) == expected_images
    for source, complete, width in probe["images"]:
        assert (folder / source).is_file(), source
        assert complete and width > 0, f"{source} did not decode in the browser"


def test_a_report_opens_in_the_browser(tmp_path, page):
    results = every_verdict()
    index = write_report(tmp_path / "report", results, {"seconds": 3.5, "jobs": 1, "gl_renderer": "test GL",
                                                       "profile": "auto: strict", "complete": True})
    listed = sum(len(result.images) for result in results)
    check_page(tmp_path / "report", page(index), listed)
    data = json.loads((tmp_path / "report" / "results.json").read_text())
    assert listed == sum(len(scene["images"]) for scene in data["scenes"])


def test_a_merged_report_opens_in_the_browser(tmp_path, page, capsys):
    from test_merge import NAMES, write_shards

    shards = write_shards(tmp_path, verdicts={"charlie": FAIL, "echo": WARN})
    assert main(["conformance", "--merge", *map(str, shards), "--report", str(tmp_path / "merged")]) == 1
    capsys.readouterr()
    check_page(tmp_path / "merged", page(tmp_path / "merged" / "index.html"), 3 * len(NAMES))


def test_the_check_sees_a_missing_picture_and_a_console_error(tmp_path, page):
    index = write_report(tmp_path / "report", every_verdict()[:2], {"gl_renderer": "test GL"})
    (tmp_path / "report" / "scene_pass" / "gl.png").unlink()
    probe = page(index)
    assert any("ERR_FILE_NOT_FOUND" in problem and "scene_pass/gl.png" in problem for problem in probe["problems"])
    assert ["scene_pass/gl.png", True, 0] in probe["images"]
    index.write_text(index.read_text().replace("</body>", "<script>console.error('planted')</script></body>"))
    (tmp_path / "report" / "scene_pass" / "gl.png").write_bytes(b"not a png")
    probe = page(index)
    assert "console.error: planted" in probe["problems"]
    assert ["scene_pass/gl.png", True, 0] in probe["images"]      # on disk, but it does not decode
