"""The site in a real browser: Debian's Chromium, driven by Playwright, loads the index, a run page
and trial pages from ``view --serve``'s server on 127.0.0.1; no request leaves it, no script from the
data runs, the trial filter works. Screenshots go to the test's folder (and to docs/images/ with
SAFEEMBODAI_SCREENSHOTS=docs)."""

from __future__ import annotations

import os
import shutil
from pathlib import Path

import pytest

playwright = pytest.importorskip("playwright.sync_api", reason="the browser extra: pip install -e '.[browser]'")
CHROMIUM = shutil.which("chromium") or shutil.which("chromium-browser")
pytestmark = [pytest.mark.slow,
              pytest.mark.skipif(CHROMIUM is None, reason="no Chromium: apt-get install chromium (.ci/run does)")]
REPO = Path(__file__).resolve().parents[3]


@pytest.fixture(scope="module")
def served(runs_dir, tmp_path_factory):
    from safeembodai_core.view import build_site
    from safeembodai_core.view.serve import SiteServer

    out = tmp_path_factory.mktemp("served")
    build_site(runs_dir, out, refresh=0)
    server = SiteServer(out, lambda: build_site(runs_dir, out), port=0, interval_s=0.5).start()
    yield server
    server.stop()


@pytest.fixture(scope="module")
def browser():
    with playwright.sync_playwright() as p:
        chromium = p.chromium.launch(executable_path=CHROMIUM, args=["--no-sandbox"])
        yield chromium
        chromium.close()


@pytest.fixture
def page(browser, served):
    context = browser.new_context(viewport={"width": 1280, "height": 900})
    page = context.new_page()
    page.requests, page.problems = [], []
    page.on("request", lambda request: page.requests.append(request.url))
    page.on("console", lambda message: page.problems.append(message.text) if message.type == "error" else None)
    page.on("pageerror", lambda error: page.problems.append(str(error)))
    page.base = served.url.rsplit("/", 1)[0]
    yield page
    assert [url for url in page.requests if not url.startswith(page.base + "/")] == []  # nothing left 127.0.0.1
    assert page.problems == []
    context.close()


def shoot(page, tmp_path: Path, name: str) -> None:
    page.screenshot(path=str(tmp_path / f"{name}.png"), full_page=True)
    if os.environ.get("SAFEEMBODAI_SCREENSHOTS") == "docs":
        page.screenshot(path=str(REPO / "docs" / "images" / f"view-{name}.png"))


def test_index_run_and_trial_pages_render(page, tmp_path):
    page.goto(f"{page.base}/index.html")
    assert page.locator("table#runs tbody tr").count() == 2
    shoot(page, tmp_path, "index")
    with page.expect_navigation():
        page.click("text=mo-40")
    assert page.locator("table#trials tbody tr").count() == 40
    assert page.locator("figure img").count() >= 5
    assert all(page.evaluate("(img) => img.naturalWidth", handle) > 0 for handle in page.query_selector_all("img"))
    page.fill("#filter", "safeembodai/attack")
    assert page.locator("table#trials tbody tr:not(.hidden)").count() == 10
    assert page.inner_text("#shown") == "10 of 40 trials"
    shoot(page, tmp_path, "run")
    link = page.locator("table#trials tbody tr:not(.hidden) a").first
    assert "safeembodai__attack" in link.get_attribute("href")
    page.goto(f"{page.base}/runs/mo-40/{link.get_attribute('href')}")
    steps = page.locator("li.step").count()
    assert steps >= 1 and page.locator("li.step img:not(.plans)").count() == 2 * steps  # camera and LiDAR
    assert 1 <= page.locator("li.step img.plans").count() <= steps  # the plans, where an answer parsed
    assert all(page.evaluate("(img) => img.naturalWidth", handle) > 0 for handle in page.query_selector_all("img"))
    page.click("li.step details summary >> nth=0")
    assert "Security" in page.inner_text("li.step details pre >> nth=0")
    shoot(page, tmp_path, "trial")


def test_a_hostile_answer_renders_as_text_and_runs_nothing(page, tmp_path):
    for name in ("flatland__safeembodai__attack__0", "flatland__baseline__no_attack__0"):
        page.goto(f"{page.base}/runs/hostile/trials/{name}.html")
        assert page.evaluate("window.__pwned") is None
        answer = page.inner_text("pre.answer >> nth=0")
        assert "<script>window.__pwned = 1</script>" in answer and "\\u202egnp.exe" in answer
        assert page.locator("img[src='x']").count() == 0
    page.locator("div.attempt").first.scroll_into_view_if_needed()
    page.screenshot(path=str(tmp_path / "hostile.png"))
    if os.environ.get("SAFEEMBODAI_SCREENSHOTS") == "docs":
        page.screenshot(path=str(REPO / "docs" / "images" / "view-hostile.png"))


def test_serve_picks_up_a_new_run(page, served, runs_dir, tmp_path):
    import time

    page.goto(f"{page.base}/index.html")
    assert page.locator("table#runs tbody tr").count() == 2
    shutil.copytree(runs_dir / "hostile", runs_dir / "hostile-copy")
    try:
        deadline = time.monotonic() + 30
        while time.monotonic() < deadline:
            page.reload()
            if page.locator("table#runs tbody tr").count() == 3:
                break
            time.sleep(0.5)
        assert page.locator("table#runs tbody tr").count() == 3
    finally:
        shutil.rmtree(runs_dir / "hostile-copy")


def test_every_page_of_the_site_loads_with_its_images(page, served):
    site = Path(served.httpd.RequestHandlerClass.keywords["directory"])
    paths = sorted(p.relative_to(site).as_posix() for p in site.rglob("*.html"))
    assert len(paths) >= 47
    for path in paths:
        page.goto(f"{page.base}/{path}")
        broken = page.evaluate("Array.from(document.images).filter(i => !i.complete || i.naturalWidth === 0)"
                               ".map(i => i.src)")
        assert broken == [], (path, broken)
