"""``safeembodai export RUN --format rrd``: each trial as a Rerun recording, read back with
rerun-sdk's own reader (``rerun.chunk.RrdReader``) and checked against the run's store: the
entities, how many times each was logged, the plans' colours and the log's text."""

from __future__ import annotations

import json
import sys
from collections import defaultdict

import pytest

rerun = pytest.importorskip("rerun", reason='needs the rerun extra: pip install -e ".[rerun]"')
from rerun.chunk import RrdReader  # noqa: E402

from safeembodai_core.ablation import Ablation, RunFolder  # noqa: E402
from safeembodai_core.cli import cli  # noqa: E402
from safeembodai_core.runs.rerun_recording import GREEN, RED  # noqa: E402
from safeembodai_core.scenario import load_scenario  # noqa: E402
from safeembodai_plugins.state.sqlite_db import SqliteStateStore  # noqa: E402


def read_recording(path):
    """Entity path -> its logged rows, each a {column: value} dict, in the order they were logged."""
    rows = defaultdict(list)
    for chunk in RrdReader(path).stream().collect().stream():
        batch = chunk.to_record_batch()
        columns = {name: batch.column(name).to_pylist() for name in batch.schema.names
                   if "Component" in str(batch.schema.field(name).metadata) or ":" in name}
        for index in range(chunk.num_rows):
            rows[chunk.entity_path.lstrip("/")].append({name: values[index] for name, values in columns.items()})
    return rows


def _rgba(colour):
    r, g, b = colour
    return (r << 24) | (g << 16) | (b << 8) | 255


HOSTILE = '\x1b[2J\u202e<script>x</script>'


@pytest.fixture(scope="module")
def exported(repo, tmp_path_factory):
    """quickstart (flatland), one trial per cell, 3 steps, a careless pilot so plans get refused."""
    from safeembodai_core.plugin.manager import load_plugins

    plugins = load_plugins(environ={})
    scenario = load_scenario(repo / "scenarios" / "quickstart.yaml", [
        "trials=1", "max_steps=3", f"instruction={json.dumps('Find the red can. ' + HOSTILE)}",
        "backend={use: mock, options: {ignore_clearance_p: 0.9, malformed_p: 0.3}}"], plugins.registry)
    folder = tmp_path_factory.mktemp("rrd") / "run"
    ablation = Ablation(scenario, plugins, RunFolder(folder))
    try:
        ablation.run()
    finally:
        ablation.close()
    from click.testing import CliRunner

    out = folder.parent / "recordings"
    done = CliRunner().invoke(cli, ["export", str(folder), "--format", "rrd", "--out", str(out)])
    assert done.exit_code == 0, done.output
    store = SqliteStateStore(folder / "results.sqlite", readonly=True)
    try:
        steps = {r.spec.trial_id: store.steps(r.spec.trial_id) for r in store.results()}
    finally:
        store.close()
    return folder, out, steps


def test_one_recording_per_trial_with_the_3d_scene(exported):
    _, out, steps = exported
    assert sorted(p.name for p in out.iterdir()) == sorted(t.replace("/", "__") + ".rrd" for t in steps)
    for trial_id, records in steps.items():
        rows = read_recording(out / (trial_id.replace("/", "__") + ".rrd"))
        for static in ("world/room", "world/robot/body"):
            assert len(rows[static]) == 1, static
        assert len(rows["world/scan"]) == len(records)  # one scan per step, in the world frame
        for image in ("images/camera_image", "images/lidar_image"):
            assert len(rows[image]) == len(records), image
        executed = sum(len(r.executed) for r in records)
        assert len(rows["world/robot"]) >= len(records) + executed - 1  # every observation and command moves it
        assert rows["world/objects/can"]
        collided = sum(1 for r in records for item in r.executed if item.result.collided)
        assert len(rows["world/collisions"]) == collided


def test_each_attempts_plan_is_drawn_green_or_red_and_the_log_has_every_attempt(exported):
    _, out, steps = exported
    colours = {_rgba(GREEN): True, _rgba(RED): False}
    drawn = refused = 0
    for trial_id, records in steps.items():
        rows = read_recording(out / (trial_id.replace("/", "__") + ".rrd"))
        for j in range(1, 5):
            attempts = [a for r in records for a in r.attempts if a.index == j - 1 and a.response is not None]
            logged = rows.get(f"world/plans/attempt_{j}", [])
            assert len(logged) == len(attempts), (trial_id, j)
            assert [colours[row["LineStrips3D:colors"][0]] for row in logged] == [a.accepted for a in attempts]
            drawn += len(logged)
            refused += sum(not a.accepted for a in attempts)
        texts = [row["TextLog:text"][0] for row in rows["log"]]
        answered = sum(len(r.attempts) for r in records)
        assert sum("the LLM answered" in t for t in texts) == answered
        assert sum(": refused: " in t or t.endswith(": accepted") for t in texts) == answered
    assert drawn and refused  # the careless pilot's plans were refused, and those are drawn too


def test_text_in_the_log_is_shown_not_obeyed(exported):
    _, out, steps = exported
    rows = read_recording(out / (next(iter(steps)).replace("/", "__") + ".rrd"))
    texts = "\n".join(row["TextLog:text"][0] for row in rows["log"])
    assert "\\x1b[2J" in texts and "\\u202e" in texts and "\x1b" not in texts and "\u202e" not in texts


def test_a_recording_is_never_written_over_and_a_missing_extra_is_said(exported, monkeypatch):
    from click.testing import CliRunner

    folder, out, steps = exported
    trial = next(iter(steps))
    target = out / (trial.replace("/", "__") + ".rrd")
    before = target.read_bytes()
    done = CliRunner().invoke(cli, ["export", str(folder), "--format", "rrd", "--trial", trial, "--out", str(target)])
    assert done.exit_code == 1 and "exists" in str(done.exception) and target.read_bytes() == before
    monkeypatch.setitem(sys.modules, "rerun", None)  # as if the extra were not installed
    done = CliRunner().invoke(cli, ["export", str(folder), "--format", "rrd", "--trial", trial,
                                    "--out", str(out / "new.rrd")])
    assert done.exit_code == 1 and 'pip install -e ".[rerun]"' in str(done.exception)
    assert not (out / "new.rrd").exists()


def test_view_links_each_trial_page_to_its_recording_in_the_run_folder(exported, tmp_path):
    """``export RUN --format rrd --out RUN/recordings`` after a site was built: rebuilt, ``view`` copies
    each recording into the site and the trial page links it; a file there that is not a recording is
    left out."""
    import shutil

    from safeembodai_core.view.site import build_site

    folder, out, steps = exported
    build_site(folder, tmp_path / "site")  # rendered before any recording was exported
    shutil.copytree(out, folder / "recordings")
    first, second = sorted(steps)[:2]
    (folder / "recordings" / (second.replace("/", "__") + ".rrd")).write_bytes(b"<html>not a recording</html>")
    try:
        build_site(folder, tmp_path / "site")
    finally:
        shutil.rmtree(folder / "recordings")
    pages = {p.stem: p.read_text(encoding="utf-8") for p in (tmp_path / "site").rglob("trials/*.html")}
    linked = [name for name, html in pages.items() if 'class="recording"' in html]
    assert len(linked) == len(steps) - 1
    [refused] = [name for name, html in pages.items() if "not a Rerun recording" in html]  # said, not linked
    assert refused == second.replace("/", "__") and refused not in linked
    [copied] = [p for p in (tmp_path / "site").rglob("recordings/*.rrd") if first.replace("/", "__") in p.name]
    assert copied.read_bytes() == (out / (first.replace("/", "__") + ".rrd")).read_bytes()
    assert not any(second.replace("/", "__") in p.name for p in (tmp_path / "site").rglob("recordings/*"))
