"""A screenshot of a trial's recording in Rerun's web viewer as ``view --serve`` serves it:
docs/images/rerun_viewer.png.

A small run of SCENARIO (one trial per cell, the mock pilot) is written and exported as recordings
in a scratch folder; ``safeembodai view --serve`` serves it; headless Chromium (WebGL on SwiftShader)
follows the trial page's "open in Rerun's web viewer" link for the trial with the largest recording,
waits until the viewer holds all of it, and saves the picture. The same steps as the browser test
(tests/core/view/test_rerun_browser.py, whose helpers this uses); prints how long each part took.

    python bench/rerun_viewer_screenshot.py [--scenario scenarios/mo.yaml] [--steps 8] [--out FILE.png]
"""

from __future__ import annotations

import argparse
import importlib.util
import tempfile
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]


def browser_test_helpers():
    helpers = REPO / "tests" / "core" / "view" / "test_rerun_browser.py"
    spec = importlib.util.spec_from_file_location("rerun_browser", helpers)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--scenario", default=str(REPO / "scenarios" / "mo.yaml"))
    parser.add_argument("--steps", type=int, default=8)
    parser.add_argument("--out", default=str(REPO / "docs" / "images" / "rerun_viewer.png"))
    args = parser.parse_args()
    helpers = browser_test_helpers()
    from playwright.sync_api import sync_playwright

    with tempfile.TemporaryDirectory() as scratch:
        root = Path(scratch)
        started = time.perf_counter()
        run = helpers.make_run(root / "runs" / "run", steps=args.steps, scenario=Path(args.scenario))
        made = time.perf_counter() - started
        recording = max((run / "recordings").glob("*.rrd"), key=lambda p: p.stat().st_size)
        expected = helpers.entities(recording.read_bytes(), root)
        size_kib = recording.stat().st_size / 1024
        served = helpers.Served(root / "runs")
        try:
            with sync_playwright() as p:
                browser = p.chromium.launch(executable_path=helpers.CHROMIUM, args=helpers.FLAGS)
                try:
                    page = browser.new_page(viewport={"width": 1600, "height": 1000})
                    started = time.perf_counter()
                    seen = helpers.open_in_viewer(page, served, f"runs/run/trials/{recording.stem}.html", expected,
                                                  root)
                    loaded = time.perf_counter() - started
                    held = helpers.entities(seen["saved"], root) if seen["saved"] else set()
                    page.screenshot(path=args.out)
                finally:
                    browser.close()
        finally:
            served.stop()
    print(f"run and recordings: {made:.1f} s; viewer opened and holding the recording: {loaded:.1f} s")
    print(f"{recording.name}: {size_kib:.0f} KiB, {len(expected)} entities, "
          f"{len(held)} held by the viewer; console errors: {len(seen['problems'])}; "
          f"calls home answered empty: {sorted({u.split('/')[2] for u in seen['outside']})}")
    print(f"wrote {args.out}")


if __name__ == "__main__":
    main()
