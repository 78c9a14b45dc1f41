"""``view --serve`` with Rerun's web viewer beside it (issue 38): a served trial page with a recording
links to ``/rerun-viewer/<the recording>``, which the site's server redirects to the viewer opening the
recording's absolute address (escaped as one query value); a ``.rrd`` -- and only a ``.rrd`` -- answers
the viewer's origin, and only it, with a CORS header; the static site keeps the plain link; without
rerun-sdk ``--serve --rerun-viewer`` serves as before and says once why there is no viewer; without
``--rerun-viewer`` (the viewer listens on every interface) none is started. No browser, no viewer
process: the viewer's port is a number here (the browser test is tests/core/view/test_rerun_browser.py)."""

from __future__ import annotations

import re
import socket
import sys
import time
import urllib.error
import urllib.request
from pathlib import Path
from urllib.parse import parse_qs, quote, urljoin, urlsplit

import pytest

from safeembodai_core.ablation import Ablation, RunFolder
from safeembodai_core.cli import cli
from safeembodai_core.errors import SafeEmbodAIError
from safeembodai_core.plugin.manager import load_plugins
from safeembodai_core.scenario import load_scenario
from safeembodai_core.runs.trial_files import recording_file
from safeembodai_core.view import rerun_viewer
from safeembodai_core.view.files import safe_name
from safeembodai_core.view.serve import SiteServer
from safeembodai_core.view.site import build_site

VIEWER_PORT = 9876  # nothing listens there: the redirect and the CORS header only name it
LINK = re.compile(r'<a class="rerun-viewer" href="([^"]+)">open in Rerun.s web viewer</a>')


@pytest.fixture(scope="module")
def runs(repo, tmp_path_factory) -> Path:
    """A folder with one run (quickstart: 4 trials, 1 step); the first trial has a recording (its
    first bytes are a recording's: what the site copies)."""
    root = tmp_path_factory.mktemp("viewer-runs")
    plugins = load_plugins(environ={})
    scenario = load_scenario(repo / "scenarios" / "quickstart.yaml", ["trials=1", "max_steps=1"], plugins.registry)
    ablation = Ablation(scenario, plugins, RunFolder(root / "quick"))
    try:
        results = ablation.run()
    finally:
        ablation.close()
    trial = sorted(r.spec.trial_id for r in results)[0]
    target = recording_file(root / "quick", trial)
    target.parent.mkdir()
    target.write_bytes(b"RRF2" + bytes(64))
    return root


def _trial(runs: Path) -> str:
    return safe_name(next((runs / "quick" / "recordings").iterdir()).stem)  # the trial's page and recording


def _page(site: Path, name: str) -> str:
    return (site / "runs" / "quick" / "trials" / f"{name}.html").read_text(encoding="utf-8")


def _get(url: str, headers: dict[str, str] | None = None) -> tuple[int, dict[str, str]]:
    class NoRedirect(urllib.request.HTTPRedirectHandler):
        def redirect_request(self, *args, **kwargs):
            return None

    opener = urllib.request.build_opener(NoRedirect)
    try:
        with opener.open(urllib.request.Request(url, headers=headers or {}), timeout=10) as response:
            return response.status, dict(response.headers)
    except urllib.error.HTTPError as error:
        return error.code, dict(error.headers)


def test_served_pages_link_the_viewer_and_the_static_site_only_the_recording(runs, tmp_path):
    site = tmp_path / "site"
    name = _trial(runs)
    build_site(runs, site)
    assert not LINK.search(_page(site, name)) and f'href="../recordings/{name}.rrd"' in _page(site, name)
    counts = build_site(runs, site, viewer=True)  # as `view --serve` with the viewer: that page anew
    assert counts["trials"] == 1
    assert LINK.findall(_page(site, name)) == [f"../../../rerun-viewer/runs/quick/recordings/{name}.rrd"]
    pages = sorted((site / "runs" / "quick" / "trials").glob("*.html"))
    assert len(pages) == 4 and sum(bool(LINK.search(p.read_text(encoding="utf-8"))) for p in pages) == 1
    assert build_site(runs, site, viewer=True)["runs"] == 0  # unchanged: nothing rendered again
    assert build_site(runs, site)["trials"] == 1  # the static site again: the plain link only
    assert not LINK.search(_page(site, name)) and f"../recordings/{name}.rrd" in _page(site, name)


def test_the_link_redirects_to_the_viewer_opening_the_recordings_absolute_address(runs, tmp_path):
    site = tmp_path / "site"
    name = _trial(runs)
    build_site(runs, site, viewer=True)
    server = SiteServer(site, lambda: None, port=0, viewer_port=VIEWER_PORT).start()
    base = server.url.rsplit("/", 1)[0]
    port = urlsplit(base).port
    try:
        page = f"{base}/runs/quick/trials/{name}.html"
        link = urljoin(page, LINK.findall(_page(site, name))[0])
        status, headers = _get(link)
        recording = f"http://127.0.0.1:{port}/runs/quick/recordings/{name}.rrd"
        assert status == 302
        assert headers["Location"] == f"http://127.0.0.1:{VIEWER_PORT}/?url={quote(recording, safe='')}"
        assert parse_qs(urlsplit(headers["Location"]).query) == {"url": [recording]}  # one value, whole
        assert _get(recording)[0] == 200
        status, headers = _get(link, {"Host": f"localhost:{port}"})  # the address the browser used
        assert headers["Location"] == (f"http://localhost:{VIEWER_PORT}/?url="
                                       + quote(recording.replace("127.0.0.1", "localhost"), safe=""))
        for path in ("/rerun-viewer/index.html", "/rerun-viewer/runs/quick/recordings/none.rrd",
                     "/rerun-viewer/runs/quick/recordings/", "/rerun-viewer/../manifest.json",
                     f"/rerun-viewer/runs/quick/recordings/%2E%2E/recordings/{name}.rrd/"):
            assert _get(base + path)[0] == 404, path
        assert _get(link, {"Host": "evil.example:80"})[0] == 421
    finally:
        server.stop()


def test_only_the_viewers_origin_may_read_a_recording_and_nothing_else(runs, tmp_path):
    site = tmp_path / "site"
    name = _trial(runs)
    build_site(runs, site, viewer=True)
    served = SiteServer(site, lambda: None, port=0, viewer_port=VIEWER_PORT).start()
    plain = SiteServer(site, lambda: None, port=0).start()
    try:
        base = served.url.rsplit("/", 1)[0]
        recording = f"{base}/runs/quick/recordings/{name}.rrd"
        for origin in (f"http://127.0.0.1:{VIEWER_PORT}", f"http://localhost:{VIEWER_PORT}"):
            status, headers = _get(recording, {"Origin": origin})
            assert status == 200 and headers["Access-Control-Allow-Origin"] == origin and headers["Vary"] == "Origin"
        for origin in ("http://evil.example", f"http://127.0.0.1:{VIEWER_PORT + 1}", "null",
                       f"https://127.0.0.1:{VIEWER_PORT}"):
            status, headers = _get(recording, {"Origin": origin})
            assert status == 200 and "Access-Control-Allow-Origin" not in headers, origin
        for path in ("/index.html", f"/runs/quick/trials/{name}.html", "/manifest.json", "/view.css"):
            status, headers = _get(base + path, {"Origin": f"http://127.0.0.1:{VIEWER_PORT}"})
            assert status == 200 and "Access-Control-Allow-Origin" not in headers, path
        plain_base = plain.url.rsplit("/", 1)[0]  # served without the viewer: no CORS, no redirect
        status, headers = _get(f"{plain_base}/runs/quick/recordings/{name}.rrd",
                               {"Origin": f"http://127.0.0.1:{VIEWER_PORT}"})
        assert status == 200 and "Access-Control-Allow-Origin" not in headers
        assert _get(f"{plain_base}/rerun-viewer/runs/quick/recordings/{name}.rrd")[0] == 404
    finally:
        served.stop()
        plain.stop()


def _serve(cli_runner, monkeypatch, args: list[str]):
    """``view --serve`` until it has served (its endless wait ends at once here)."""
    real_sleep = time.sleep

    def sleep(seconds: float) -> None:
        if seconds == 3600:
            raise KeyboardInterrupt
        real_sleep(seconds)

    monkeypatch.setattr(time, "sleep", sleep)
    return cli_runner.invoke(cli, ["view", *args, "--serve", "--port", "0"])


def test_without_rerun_sdk_serve_works_and_says_once_why_there_is_no_viewer(runs, tmp_path, cli_runner,
                                                                           monkeypatch):
    monkeypatch.setitem(sys.modules, "rerun", None)  # as if the extra were not installed
    site = tmp_path / "site"
    done = _serve(cli_runner, monkeypatch, [str(runs), "--out", str(site), "--rerun-viewer"])
    assert done.exit_code == 0, done.output
    said = " ".join(done.output.split())
    assert said.count("Rerun's web viewer is not served") == 1
    assert 'rerun-sdk is not installed (pip install -e ".[rerun]")' in said and "serving http://127.0.0.1:" in said
    assert not LINK.search(_page(site, _trial(runs))) and ".rrd" in _page(site, _trial(runs))


def test_serve_with_the_viewer_links_it_and_warns_it_listens_on_every_interface(runs, tmp_path, cli_runner,
                                                                                 monkeypatch):
    monkeypatch.setattr(rerun_viewer, "start_web_viewer", lambda port: 4321 if port == 0 else port)
    site = tmp_path / "site"
    done = _serve(cli_runner, monkeypatch, [str(runs), "--out", str(site), "--rerun-viewer"])
    assert done.exit_code == 0, done.output
    said = " ".join(done.output.split())
    assert "Rerun's web viewer on port 4321" in said and "Warning: it listens on every interface (0.0.0.0" in said
    assert LINK.search(_page(site, _trial(runs)))


def test_the_viewer_is_served_only_when_asked(runs, tmp_path, cli_runner, monkeypatch):
    """Rerun's web viewer listens on 0.0.0.0 (rerun-sdk has no option for the address): ``--serve`` alone,
    with rerun-sdk installed, serves the site on 127.0.0.1 and no viewer."""
    started: list[int] = []
    monkeypatch.setitem(sys.modules, "rerun", type(sys)("rerun"))  # as if the extra were installed
    monkeypatch.setattr(rerun_viewer, "start_web_viewer", lambda port: started.append(port) or 4321)
    site = tmp_path / "site"
    done = _serve(cli_runner, monkeypatch, [str(runs), "--out", str(site)])
    assert done.exit_code == 0, done.output
    said = " ".join(done.output.split())
    assert started == [] and "Rerun's web viewer" not in said and "serving http://127.0.0.1:" in said
    assert not LINK.search(_page(site, _trial(runs))) and ".rrd" in _page(site, _trial(runs))
    asked = cli_runner.invoke(cli, ["view", str(runs), "--out", str(tmp_path / "static"), "--rerun-viewer"])
    assert asked.exit_code == 2 and "needs --serve" in asked.output and started == []


def test_the_viewer_is_refused_without_rerun_or_on_a_taken_port(monkeypatch):
    with monkeypatch.context() as patched:
        patched.setitem(sys.modules, "rerun", None)
        with pytest.raises(rerun_viewer.ViewerUnavailable, match=re.escape('pip install -e ".[rerun]"')):
            rerun_viewer.start_web_viewer(0)
    pytest.importorskip("rerun", reason='needs the rerun extra: pip install -e ".[rerun]"')
    with socket.socket() as taken:
        taken.bind(("0.0.0.0", 0))
        taken.listen()
        port = taken.getsockname()[1]
        with pytest.raises(SafeEmbodAIError, match=f"cannot listen on port {port}.*--viewer-port"):
            rerun_viewer.start_web_viewer(port)
