"""``view`` of a folder that holds other outputs of the framework than runs: each is listed as left
out, with why, on the index and in the line the command prints (issue 38)."""

from __future__ import annotations

from safeembodai_core.ablation import Ablation, RunFolder
from safeembodai_core.cli import cli
from safeembodai_core.plugin.manager import load_plugins
from safeembodai_core.scenario import load_scenario
from safeembodai_core.view.site import build_site


def _tiny_run(folder, repo):
    plugins = load_plugins(environ={})
    scenario = load_scenario(repo / "scenarios" / "quickstart.yaml", ["trials=1", "max_steps=1"], plugins.registry)
    ablation = Ablation(scenario, plugins, RunFolder(folder))
    try:
        ablation.run()
    finally:
        ablation.close()


def test_a_run_folder_of_safeembodai_run_and_a_bare_store_are_listed_as_left_out(repo, tmp_path, cli_runner):
    runs = tmp_path / "runs"
    _tiny_run(runs / "quick", repo)
    (runs / "one-trial").mkdir()
    (runs / "one-trial" / "trial.json").write_text("{}")
    (runs / "X" / "damaged").mkdir(parents=True)
    (runs / "X" / "damaged" / "finished.jsonl").write_text("")
    (runs / "notes").mkdir()  # not ours: nothing to say about it
    counts = build_site(runs, tmp_path / "site")
    assert counts["found"] == 1
    assert [name for name, _ in counts["skipped"]] == ["X/damaged", "one-trial"]
    index = (tmp_path / "site" / "index.html").read_text(encoding="utf-8")
    assert "Left out" in index and "one-trial: a &#39;safeembodai run&#39; folder: one trial" in index
    assert "notes" not in index
    done = cli_runner.invoke(cli, ["view", str(runs), "--out", str(tmp_path / "site2")])
    assert done.exit_code == 0, done.output
    assert "left out one-trial: a 'safeembodai run' folder" in " ".join(done.output.split())
