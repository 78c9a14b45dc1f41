"""A spending cap: ``ablate --max-tokens`` / ``--max-cost`` stop a run cleanly once its finished trials
used that much, say how to go on, lose nothing recorded; a cap that cannot be priced is refused before
anything runs."""

from __future__ import annotations

import subprocess
import sys

import pytest

from safeembodai_core.ablation.spending import SpendingCap, SpendingCapReached
from safeembodai_core.errors import SafeEmbodAIError
from safeembodai_core.models import Outcome, TrialResult, TrialSpec


def _result(prompt, completion):
    spec = TrialSpec(trial_id="OF/a/c/0", environment="OF", arm="a", condition="c", index=0, seed=0)
    return TrialResult(spec=spec, outcome=Outcome.COMPLETED, steps=1, prompt_tokens=prompt,
                       completion_tokens=completion)


def test_the_cap_counts_tokens_and_cost_and_stops_once_reached():
    cap = SpendingCap(max_tokens=1000)
    cap.add(_result(600, 100))
    with pytest.raises(SpendingCapReached, match="--max-tokens 1000 reached: the finished trials used 1400 tokens"):
        cap.add(_result(600, 100))
    priced = SpendingCap(max_cost=0.01, price=lambda p, c: p * 2.5e-6 + c * 1e-5)
    priced.add(_result(2000, 400))  # $0.009
    with pytest.raises(SpendingCapReached, match=r"--max-cost 0.01 reached: the finished trials cost \$0.0180"):
        priced.add(_result(2000, 400))
    with pytest.raises(SafeEmbodAIError, match="--max-cost needs the model's price"):
        SpendingCap(max_cost=1.0, price=lambda p, c: None)


@pytest.mark.slow
def test_ablate_stops_at_the_token_cap_and_a_resume_finishes_the_run(repo, tmp_path):
    command = [sys.executable, "-m", "safeembodai_core", "ablate", str(repo / "scenarios" / "quickstart.yaml"),
               "--backend", "mock", "--set", "trials=3", "--no-report", "--out", str(tmp_path)]
    capped = subprocess.run([*command, "--max-tokens", "1"], capture_output=True, text=True, timeout=300)
    assert capped.returncode == 1
    [run] = tmp_path.iterdir()
    assert "--max-tokens 1 reached" in capped.stderr
    assert f"resume with --resume {run}" in capped.stderr.replace("\n", "")
    finished = (run / "finished.jsonl").read_text().splitlines()
    assert 1 <= len(finished) < 12
    resumed = subprocess.run([sys.executable, "-m", "safeembodai_core", "ablate", "--resume", str(run), "--no-report"],
                             capture_output=True, text=True, timeout=300)
    assert resumed.returncode == 0, resumed.stderr[-2000:]
    assert len((run / "finished.jsonl").read_text().splitlines()) == 12


@pytest.mark.slow
def test_a_cost_cap_for_a_pilot_without_a_price_is_refused_before_any_folder(repo, tmp_path):
    done = subprocess.run([sys.executable, "-m", "safeembodai_core", "ablate",
                           str(repo / "scenarios" / "quickstart.yaml"), "--max-cost", "1", "--out",
                           str(tmp_path / "runs")], capture_output=True, text=True,
                          timeout=120)
    assert done.returncode != 0 and "--max-cost needs the model's price" in done.stderr
    assert not (tmp_path / "runs").exists()


def test_the_last_trial_crossing_the_cap_ends_a_complete_run_and_a_recorded_cost_is_used():
    cap = SpendingCap(max_tokens=100)
    cap.add(_result(600, 100), more=False)  # nothing left to stop: the run is complete
    priced = SpendingCap(max_cost=1.0, price=lambda p, c: 0.0)
    recorded = _result(10, 10).model_copy(update={"cost_usd": 2.0})
    with pytest.raises(SpendingCapReached, match=r"\$2.0000"):
        priced.add(recorded)  # the trial's own cost, not a new pricing


def test_a_price_that_fails_is_a_clear_error():
    def broken(p, c):
        raise RuntimeError("no table")

    with pytest.raises(SafeEmbodAIError, match="--max-cost: the backend's price failed \\(RuntimeError: no table\\)"):
        SpendingCap(max_cost=1.0, price=broken)


@pytest.mark.parametrize("said", [None, float("nan"), -1.0, "0.5", RuntimeError("table gone")],
                         ids=["none", "nan", "negative", "text", "raises"])
def test_a_trial_the_price_cannot_price_stops_the_cost_cap_never_counts_as_free(said):
    """The price knew the model at the start; a trial it then cannot price is an unknown cost, not $0."""
    def price(p, c):
        if (p, c) == (1000, 1000):
            return 0.01
        if isinstance(said, Exception):
            raise said
        return said

    cap = SpendingCap(max_cost=100.0, price=price)
    with pytest.raises(SpendingCapReached, match=r"trial OF/a/c/0 has no price .* what the run spent is unknown"):
        cap.add(_result(600, 100))
    cap.add(_result(0, 0))  # a trial that used no token costs nothing, priced or not
