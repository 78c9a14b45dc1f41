"""A run folder from someone else cannot make ``view`` write or serve files outside the site, nor
copy in files it points to (review findings: symlinks, special files, foreign hosts)."""

from __future__ import annotations

import os
import shutil
import urllib.error
import urllib.request
from pathlib import Path

import pytest

from safeembodai_core.errors import SafeEmbodAIError
from safeembodai_core.view import build_site
from safeembodai_core.view.files import Site, read_run_file
from safeembodai_core.view.report_tables import report_tables
from safeembodai_core.view.serve import SiteServer

pytestmark = pytest.mark.slow  # each builds whole sites of runs (module fixtures of 14-18 s)


@pytest.fixture
def run(runs_dir, tmp_path) -> Path:
    folder = tmp_path / "runs" / "hostile"
    shutil.copytree(runs_dir / "hostile", folder)
    return folder


def test_a_planted_site_folder_symlink_is_refused(run, tmp_path):
    victim = tmp_path / "victim"
    victim.mkdir()
    (run / "view").symlink_to(victim)
    with pytest.raises(SafeEmbodAIError, match="is a symlink"):
        build_site(run, run / "view")
    assert list(victim.iterdir()) == []
    foreign = tmp_path / "foreign"
    foreign.mkdir()
    (foreign / "notes.txt").write_text("mine")
    with pytest.raises(SafeEmbodAIError, match="no site of ours"):
        build_site(run, foreign)


def test_symlinks_inside_a_site_are_replaced_or_refused_never_written_through(run, tmp_path):
    out = tmp_path / "site"
    build_site(run, out)
    victim = tmp_path / "victim.txt"
    victim.write_text("precious")
    page = out / "runs" / "hostile" / "index.html"
    page.unlink()
    page.symlink_to(victim)  # a page planted as a symlink: replaced by the new page
    (out / "manifest.json").write_text("{}")  # render everything anew
    build_site(run, out)
    assert victim.read_text() == "precious" and not page.is_symlink() and "<html" in page.read_text()
    outside = tmp_path / "outside"
    outside.mkdir()
    trials = out / "runs" / "hostile" / "trials"
    shutil.rmtree(trials)
    trials.symlink_to(outside)  # a folder planted as a symlink: refused
    (out / "manifest.json").write_text("{}")
    with pytest.raises(SafeEmbodAIError, match="outside the site"):
        Site(out).write("runs/hostile/trials/x.html", "x")
    build_site(run, out)  # the run is reported unreadable rather than written outside
    assert list(outside.iterdir()) == [] and "unreadable" in (out / "index.html").read_text()


def test_files_a_run_folder_points_elsewhere_are_not_copied(run, tmp_path):
    secret = tmp_path / "secret.png"
    secret.write_bytes(b"\x89PNG\r\n\x1a\nTOP-SECRET")
    figures = run / "figures"
    figures.mkdir(exist_ok=True)
    (figures / "zz_leak.png").symlink_to(secret)
    trajectory = next((run / "trajectories").glob("*.png"))
    trajectory.unlink()
    trajectory.symlink_to(secret)
    out = tmp_path / "site"
    build_site(run, out)
    for path in out.rglob("*"):
        if path.is_file():
            assert b"TOP-SECRET" not in path.read_bytes(), path
    assert read_run_file(secret, png=True) is not None and read_run_file(figures / "zz_leak.png") is None


def test_a_run_folders_symlinked_folders_are_not_followed_and_the_pages_say_so(run, tmp_path):
    """figures/ and trajectories/ as symlinks to folders outside, holding files of the very names the site
    would copy: none is copied, and each page says what was left out and why; a symlinked recordings/
    (whose marker says whether the run records) makes the run unreadable, its row saying why."""
    trajectories = sorted((run / "trajectories").glob("*.png"))
    outside = {name: tmp_path / "outside" / name for name in ("figures", "trajectories", "recordings")}
    for folder in outside.values():
        folder.mkdir(parents=True)
    (outside["figures"] / "moer.png").write_bytes(b"\x89PNG\r\n\x1a\nTOP-SECRET")
    for picture in trajectories:
        (outside["trajectories"] / picture.name).write_bytes(b"\x89PNG\r\n\x1a\nTOP-SECRET")
        (outside["recordings"] / f"{picture.stem}.rrd").write_bytes(b"RRF2TOP-SECRET")
    for name in ("figures", "trajectories"):
        shutil.rmtree(run / name, ignore_errors=True)
        (run / name).symlink_to(outside[name])
    out = tmp_path / "site"

    def nothing_copied() -> None:
        for path in out.rglob("*"):
            if path.is_file():
                assert b"TOP-SECRET" not in path.read_bytes(), path

    build_site(run, out)
    nothing_copied()
    page = (out / "runs" / "hostile" / "index.html").read_text(encoding="utf-8")
    assert "left out figures/: figures is a symlink (not followed)" in page
    trial = next((out / "runs" / "hostile" / "trials").glob("*.html")).read_text(encoding="utf-8")
    assert "left out trajectories/" in trial and "trajectories is a symlink (not followed)" in trial
    (run / "recordings").symlink_to(outside["recordings"])
    build_site(run, out)
    nothing_copied()
    assert "recordings is a symlink (not followed)" in (out / "index.html").read_text(encoding="utf-8")


@pytest.mark.skipif(not hasattr(os, "mkfifo"), reason="no FIFOs here")
def test_a_report_that_is_a_fifo_or_a_device_is_not_read(tmp_path):
    fifo = tmp_path / "report.md"
    os.mkfifo(fifo)
    assert report_tables(fifo) == []  # returns at once: never blocks on the FIFO
    assert report_tables(Path("/dev/zero")) == []


def test_the_server_serves_the_site_only(run, tmp_path):
    out = tmp_path / "site"
    build_site(run, out)
    secret = tmp_path / "secret.txt"
    secret.write_text("TOP-SECRET")
    (out / "leak.txt").symlink_to(secret)
    (out / ".draft.html.partial").write_text("half")
    server = SiteServer(out, lambda: None, port=0).start()
    base = server.url.rsplit("/", 1)[0]

    def status(path: str, host: str | None = None) -> int:
        request = urllib.request.Request(base + path, headers={"Host": host} if host else {})
        try:
            with urllib.request.urlopen(request, timeout=10) as response:
                return response.status
        except urllib.error.HTTPError as error:
            return error.code

    try:
        assert status("/index.html") == 200
        assert status("/leak.txt") == 404 and status("/runs/") == 404 and status("/.draft.html.partial") == 404
        assert status("/index.html", host="evil.example:80") == 421
        with urllib.request.urlopen(base + "/", timeout=10) as response:  # the bare address: the index
            assert response.status == 200 and response.url.endswith("/index.html")
        assert status("/", host="evil.example:80") == 421
    finally:
        server.stop()
