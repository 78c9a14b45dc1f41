"""A trial's recording opened in Rerun's web viewer, served by ``view --serve``, in headless Chromium
(issue 38): ``safeembodai view RUNS --serve`` in a subprocess; the trial page's "open in Rerun's web
viewer" link is followed; the viewer fetches the recording from the site's server (200, allowed to
its origin by CORS) and holds it -- what it saves back (``save_recording()``, the viewer's own
encoding) has the recording's entities, read with rerun-sdk's reader -- with its canvas shown, no
error overlay and no console error. WebGL on SwiftShader (no GPU). The viewer's own requests to the
internet (fonts, an update check, its telemetry) are answered empty here: the test machine is offline.
``SAFEEMBODAI_SCREENSHOTS=docs`` also writes docs/images/rerun_viewer.png (``bench/rerun_viewer_screenshot.py``
is the same with a larger trial)."""

from __future__ import annotations

import os
import re
import shutil
import subprocess
import sys
import time
from pathlib import Path
from urllib.parse import urlsplit

import pytest

pytest.importorskip("rerun", reason='needs the rerun extra: pip install -e ".[rerun]"')
playwright = pytest.importorskip("playwright.sync_api", reason="the browser extra: pip install -e '.[browser]'")
CHROMIUM = shutil.which("chromium") or shutil.which("chromium-browser")
pytestmark = [pytest.mark.slow,
              pytest.mark.skipif(CHROMIUM is None, reason="no Chromium: apt-get install chromium (.ci/run does)")]
REPO = Path(__file__).resolve().parents[3]
#: WebGL 2 on the CPU: no GPU in CI (the viewer asks for WebGPU first and falls back to WebGL).
FLAGS = ["--no-sandbox", "--use-angle=swiftshader", "--enable-unsafe-swiftshader", "--ignore-gpu-blocklist"]
#: Where Rerun's web viewer (rerun-sdk 0.41) goes by itself: its font, the latest release, telemetry.
VIEWER_CALLS_HOME = {"fonts.googleapis.com", "fonts.gstatic.com", "api.github.com", "tel.rerun.io"}


def make_run(folder: Path, steps: int = 3, scenario: Path = REPO / "scenarios" / "quickstart.yaml") -> Path:
    """``scenario`` (quickstart: flatland, the mock pilot), one trial per cell, exported as recordings."""
    from click.testing import CliRunner

    from safeembodai_core.ablation import Ablation, RunFolder
    from safeembodai_core.cli import cli
    from safeembodai_core.plugin.manager import load_plugins
    from safeembodai_core.scenario import load_scenario

    plugins = load_plugins(environ={})
    ablation = Ablation(load_scenario(scenario, ["trials=1", f"max_steps={steps}"], plugins.registry), plugins,
                        RunFolder(folder))
    try:
        ablation.run()
    finally:
        ablation.close()
    done = CliRunner().invoke(cli, ["export", str(folder), "--format", "rrd", "--out", str(folder / "recordings")])
    assert done.exit_code == 0, done.output
    return folder


class Served:
    """``safeembodai view RUNS --serve --port 0 --rerun-viewer`` in a subprocess, until stopped."""

    def __init__(self, runs: Path) -> None:
        self.process = subprocess.Popen([sys.executable, "-m", "safeembodai_core", "view", str(runs), "--serve",
                                         "--port", "0", "--rerun-viewer"], stdout=subprocess.PIPE,
                                        stderr=subprocess.STDOUT, text=True, env={**os.environ, "COLUMNS": "400"})
        self.lines: list[str] = []
        self.url = ""
        deadline = time.monotonic() + 180
        while not self.url and time.monotonic() < deadline:
            line = self.process.stdout.readline() if self.process.stdout else ""
            if not line:
                break
            self.lines.append(line)
            found = re.search(r"serving (http://\S+)/index\.html", line)
            self.url = found.group(1) if found else ""
        assert self.url, "".join(self.lines)

    def listening(self) -> set[int] | None:
        """The ports the process listens on (None without psutil)."""
        try:
            import psutil
        except ImportError:
            return None
        return {c.laddr.port for c in psutil.Process(self.process.pid).net_connections(kind="inet")
                if c.status == psutil.CONN_LISTEN}

    def stop(self) -> None:
        self.process.terminate()
        self.process.wait(timeout=30)


def open_in_viewer(page, served: Served, trial_page: str, expected: set[str], scratch: Path,
                   timeout_s: float = 120.0) -> dict:
    """Follow the trial page's link to the viewer; wait until the viewer holds the recording: what it
    saves back has the ``expected`` entities (it streams a recording in: the first chunks come first).
    Returns what was seen: the recording's response, the bytes the viewer saves back, the outside calls."""
    seen: dict = {"outside": [], "problems": [], "recording": None, "saved": b""}
    page.on("console", lambda message: seen["problems"].append(message.text) if message.type == "error" else None)
    page.on("pageerror", lambda error: seen["problems"].append(str(error)))

    def outside(route) -> None:  # offline here: the viewer's own calls home get an empty answer
        seen["outside"].append(route.request.url)
        route.fulfill(status=200, body="", headers={"Access-Control-Allow-Origin": "*", "Content-Type": "text/plain"})

    page.route(re.compile(r"^(?!http://127\.0\.0\.1[:/]).*"), outside)
    page.on("response", lambda response: seen.__setitem__("recording", response)
            if urlsplit(response.url).path.endswith(".rrd") and response.request.method == "GET" else None)
    page.goto(f"{served.url}/{trial_page}")
    link = page.locator("a.rerun-viewer")
    assert link.count() == 1 and link.inner_text() == "open in Rerun's web viewer"
    with page.expect_navigation():
        link.click()
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        saved = bytes(page.evaluate(
            "() => { try { return Array.from(window._handle.save_recording()) } catch (e) { return [] } }"))
        if saved and entities(saved, scratch) >= expected:
            seen["saved"] = saved
            break
        page.wait_for_timeout(500)
    page.wait_for_timeout(3000)  # a few frames drawn (screenshots; a late error would show)
    return seen


def entities(data: bytes, tmp_path: Path) -> set[str]:
    from rerun.chunk import RrdReader

    path = tmp_path / f"read-{len(data)}.rrd"
    path.write_bytes(data)
    return {chunk.entity_path.lstrip("/") for chunk in RrdReader(path).stream().collect().stream()}


@pytest.fixture(scope="module")
def runs(tmp_path_factory) -> Path:
    root = tmp_path_factory.mktemp("rerun-browser")
    make_run(root / "quick")
    return root


def test_a_recording_opens_in_the_served_web_viewer_with_no_console_error(runs, tmp_path):
    served = Served(runs)
    try:
        recording = max((runs / "quick" / "recordings").glob("*.rrd"), key=lambda p: p.stat().st_size)
        said = " ".join(" ".join(served.lines).split())
        assert "Rerun's web viewer on port" in said and "not served" not in said
        with playwright.sync_playwright() as p:
            browser = p.chromium.launch(executable_path=CHROMIUM, args=FLAGS)
            try:
                page = browser.new_page(viewport={"width": 1400, "height": 900})
                expected = entities(recording.read_bytes(), tmp_path)
                assert {"world/room", "world/robot", "world/robot/body", "world/scan", "log"} <= expected
                seen = open_in_viewer(page, served, f"runs/quick/trials/{recording.stem}.html", expected, tmp_path)
                viewer = urlsplit(page.url)
                assert viewer.port != urlsplit(served.url).port and viewer.hostname == "127.0.0.1"
                assert served.listening() in (None, {urlsplit(served.url).port, viewer.port})  # no gRPC server
                response = seen["recording"]
                assert response is not None and response.status == 200
                assert response.url == f"{served.url}/runs/quick/recordings/{recording.name}"
                assert response.headers.get("access-control-allow-origin") == f"http://127.0.0.1:{viewer.port}"
                assert page.get_attribute("#the_canvas_id", "class") == "visible"
                overlay = page.inner_text("#center_text")
                assert "error" not in overlay.lower() and "crashed" not in overlay.lower(), overlay
                assert seen["problems"] == []
                assert {urlsplit(url).hostname for url in seen["outside"]} <= VIEWER_CALLS_HOME, seen["outside"]
                assert entities(seen["saved"], tmp_path) == expected  # the whole recording, as served
                page.screenshot(path=str(tmp_path / "rerun_viewer.png"))
                if os.environ.get("SAFEEMBODAI_SCREENSHOTS") == "docs":
                    page.screenshot(path=str(REPO / "docs" / "images" / "rerun_viewer.png"))
            finally:
                browser.close()
    finally:
        served.stop()
