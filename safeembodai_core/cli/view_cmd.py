"""``safeembodai view RUNS``: every run in a browser (``safeembodai_core.view``)."""

from __future__ import annotations

import click


@click.command("view")
@click.argument("source", metavar="RUNS_DIR_OR_RUN", type=click.Path(file_okay=False, exists=True))
@click.option("--out", type=click.Path(file_okay=False), default=None,
              help="The site's folder (default: SOURCE/_view for a folder of runs, RUN/view for one run).")
@click.option("--serve", is_flag=True, help="Serve the site and pick up new runs while they are written.")
@click.option("--host", default="127.0.0.1", show_default=True, help="Address to serve on (with --serve).")
@click.option("--port", type=click.IntRange(0, 65535), default=8000, show_default=True,
              help="Port to serve on (0: any free one).")
@click.option("--rerun-viewer", is_flag=True,
              help="With --serve: also serve Rerun's web viewer (rerun-sdk), which listens on EVERY interface "
                   "(0.0.0.0: rerun-sdk has no option for the address).")
@click.option("--viewer-port", type=click.IntRange(0, 65535), default=0, show_default=True,
              help="Port for Rerun's web viewer, with --rerun-viewer (0: any free one).")
def view(source: str, out: str | None, serve: bool, host: str, port: int, rerun_viewer: bool,
         viewer_port: int) -> None:
    """Write a static site of every run in RUNS_DIR_OR_RUN (index, run pages, trial pages)."""
    import time
    from pathlib import Path

    from rich.console import Console

    from ..runs.folder import SCENARIO_FILE
    from ..plugin.manager import load_plugins
    from ..trust.text import terminal_markup
    from ..view import build_site
    from ..view.rerun_viewer import ViewerUnavailable, start_web_viewer
    from ..view.serve import SiteServer

    if rerun_viewer and not serve:
        raise click.UsageError("--rerun-viewer serves Rerun's web viewer beside the site: it needs --serve")
    root = Path(source)
    target = Path(out) if out else root / ("view" if (root / SCENARIO_FILE).is_file() else "_view")
    plugins = load_plugins()
    console = Console(stderr=True, emoji=False)
    refresh = 5 if serve else 0
    viewer: int | None = None
    if rerun_viewer:  # before the build: the trial pages with a recording link to the viewer
        try:
            viewer = start_web_viewer(viewer_port)
        except ViewerUnavailable as unavailable:
            console.print(f"Rerun's web viewer is not served: {terminal_markup(str(unavailable))}; the trial pages "
                          "link their recordings only")
    with console.status("rendering"):
        counts = build_site(root, target, plugins, refresh=refresh, viewer=viewer is not None, parallel=True)
    console.print(f"{counts['found']} run(s) found, {counts['runs']} rendered anew ({counts['trials']} trial "
                  f"page(s)), the others unchanged, into {terminal_markup(str(target))}")
    for name, why in counts["skipped"]:
        console.print(f"left out {terminal_markup(name)}: {terminal_markup(why)}")
    if not serve:
        console.print(f"open {terminal_markup(str(target / 'index.html'))}")
        return
    server = SiteServer(target, lambda: build_site(root, target, plugins, refresh=refresh, viewer=viewer is not None,
                                                   parallel=True), host, port, viewer_port=viewer).start()
    if viewer is not None:
        console.print(f"Rerun's web viewer on port {viewer}: each trial page with a recording links to it. Warning: "
                      "it listens on every interface (0.0.0.0; rerun-sdk has no option for the address), so "
                      "anyone who can reach this machine can load the viewer (the recordings stay on the site's "
                      f"server, {terminal_markup(host)})")
    console.print(f"serving {terminal_markup(server.url)} (Ctrl-C to stop)")
    try:
        while True:
            time.sleep(3600)
    except KeyboardInterrupt:
        pass
    finally:
        server.stop()
