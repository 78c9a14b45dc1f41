"""Trials in flight in threads (``ablate --concurrency K``): the same trials and the same metrics as one
at a time, the workers' threads each with their own world, and the options checked before anything runs."""

from __future__ import annotations

import subprocess
import sys

import pytest

from safeembodai_core.ablation.plan import AblationError, executor_name


def _ablate(repo, scenario, out, *args):
    done = subprocess.run([sys.executable, "-m", "safeembodai_core", "ablate", str(repo / "scenarios" / scenario),
                           "--out", str(out), *args], capture_output=True, text=True, timeout=600)
    assert done.returncode == 0, done.stderr[-3000:]
    [run] = out.iterdir()
    return run, done.stdout


@pytest.mark.slow
@pytest.mark.parametrize(("scenario", "overrides"), [
    ("quickstart.yaml", ["--set", "trials=4"]),
    ("mo.yaml", ["--set", "trials=2", "--set", "max_steps=4"]),  # pybullet rooms: a client per thread
])
@pytest.mark.slow
def test_trials_in_flight_give_the_same_metrics_as_one_at_a_time(repo, tmp_path, scenario, overrides):
    serial, _ = _ablate(repo, scenario, tmp_path / "serial", *overrides)
    threaded, said = _ablate(repo, scenario, tmp_path / "threaded", *overrides, "--concurrency", "4")
    assert "4 in flight per worker" in said
    assert (threaded / "metrics.csv").read_bytes() == (serial / "metrics.csv").read_bytes()
    assert (threaded / "report.md").read_text().split("## Figures")[0] == \
        (serial / "report.md").read_text().split("## Figures")[0]


def test_concurrency_runs_in_worker_processes_and_is_refused_where_it_cannot_run():
    assert executor_name(1, None, None, 8) == "process"
    assert executor_name(2, "ray", None, 8) == "ray"
    assert executor_name(1, None, None, 1) == "serial"
    with pytest.raises(AblationError, match="--executor serial runs one trial at a time, not --concurrency 4: "
                                            "drop --concurrency"):
        executor_name(1, "serial", None, 4)
    with pytest.raises(AblationError, match="--concurrency must be at least 1"):
        executor_name(1, None, None, 0)


def test_a_memory_store_cannot_take_trials_in_flight(repo, cli_runner, tmp_path):
    from safeembodai_core.cli import cli

    result = cli_runner.invoke(cli, ["ablate", str(repo / "scenarios" / "quickstart.yaml"), "--set", "state=memory",
                                      "--concurrency", "2", "--out", str(tmp_path)])
    assert result.exit_code != 0
    assert "--concurrency/--executor process needs a persistent state store" in str(result.exception)
    assert not list(tmp_path.iterdir())
