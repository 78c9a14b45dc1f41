"""Ablation throughput and the framework's own overhead per step.

1. Trials per minute with 1 and 2 worker processes (and with Ray, if installed), same trials;
   the ratio 2-workers / 1-worker (target >= 1.8x on 2 cores).
2. In one process: the share of a step spent outside the backend call and the simulator
   (prompt building, image encoding, parsing, validation, recording): target <= 10%.

    python bench/ablate_throughput.py [SCENARIO] [--trials 4] [--set key=value ...]

Defaults to scenarios/mo.yaml with the mock backend.
"""

from __future__ import annotations

import argparse
import sys
import tempfile
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]


def timed_ablation(scenario, plugins, workers: int, executor: str | None) -> tuple[float, int, float]:
    """Wall time of the whole run, trials run, and steady-state seconds per trial.

    Steady state is measured between the first and the last finished trial, so it leaves out the
    one-off cost of starting workers (imports, physics clients), which a short benchmark magnifies.
    """
    from safeembodai_core.ablation import Ablation, RunFolder

    finished: list[float] = []
    with tempfile.TemporaryDirectory() as root:
        ablation = Ablation(scenario, plugins, RunFolder(Path(root) / "run"), workers=workers, executor=executor)
        started = time.perf_counter()
        try:
            results = ablation.run(lambda result: finished.append(time.perf_counter()))
        finally:
            ablation.close()
        steady = (finished[-1] - finished[0]) / (len(finished) - 1) if len(finished) > 1 else float("nan")
        return time.perf_counter() - started, len(results), steady


class Stopwatch:
    """Wraps an object and adds the time spent in its methods to ``total``."""

    def __init__(self, inner, methods):
        self._inner, self._methods, self.total = inner, set(methods), 0.0

    def __getattr__(self, name):
        value = getattr(self._inner, name)
        if name not in self._methods:
            return value

        def wrapper(*args, **kwargs):
            started = time.perf_counter()
            try:
                return value(*args, **kwargs)
            finally:
                self.total += time.perf_counter() - started

        return wrapper


def overhead_share(scenario, plugins) -> tuple[float, float, float, float, int]:
    from safeembodai_core.loop import run_trial
    from safeembodai_core.runs.runner import ScenarioRunner

    scratch = tempfile.TemporaryDirectory()
    runner = ScenarioRunner(scenario, plugins, run_dir=scratch.name)
    env_time = backend_time = total = 0.0
    steps = 0
    try:
        for spec in runner.specs():
            parts = runner.parts(spec)
            env = Stopwatch(parts.environment, ["reset", "observe", "execute", "outcome", "pose"])
            env.robot = parts.environment.robot
            backend = Stopwatch(parts.backend, ["complete"])
            parts.environment, parts.backend = env, backend
            started = time.perf_counter()
            result = run_trial(spec, parts, runner.settings(spec.arm), plugins)
            total += time.perf_counter() - started
            env_time += env.total
            backend_time += backend.total
            steps += result.steps
    finally:
        runner.close()
        scratch.cleanup()
    framework = total - env_time - backend_time
    return framework / total, total, env_time, backend_time, steps


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("scenario", nargs="?", default=str(REPO / "scenarios" / "mo.yaml"))
    parser.add_argument("--trials", type=int, default=4, help="trials per cell")
    parser.add_argument("--set", dest="overrides", action="append", default=[])
    args = parser.parse_args()

    from safeembodai_core.plugin.manager import load_plugins
    from safeembodai_core.scenario import load_scenario

    plugins = load_plugins()
    overrides = [f"trials={args.trials}", "state=sqlite", *args.overrides]
    scenario = load_scenario(args.scenario, overrides, plugins.registry)
    out = sys.stdout
    out.write(f"scenario {scenario.name}: {len(scenario.cells())} cells x {scenario.trials} trials, "
              f"backend {scenario.backend.use}\n")
    one, count, one_steady = timed_ablation(scenario, plugins, 1, "serial")
    two, _, two_steady = timed_ablation(scenario, plugins, 2, "process")
    out.write(f"1 worker : {count / one * 60:7.1f} trials/min ({one:.1f} s); "
              f"steady state {60 / one_steady:7.1f} trials/min\n")
    out.write(f"2 workers: {count / two * 60:7.1f} trials/min ({two:.1f} s); "
              f"steady state {60 / two_steady:7.1f} trials/min\n")
    out.write(f"speed-up 2 vs 1 worker: {one / two:.2f}x overall, "
              f"{one_steady / two_steady:.2f}x steady state (target >= 1.8x)\n")
    try:
        import ray  # noqa: F401
    except ImportError:
        out.write("ray      : not installed (pip install -e '.[ray]')\n")
    else:
        with_ray, _, ray_steady = timed_ablation(scenario, plugins, 2, "ray")
        out.write(f"ray (2)  : {count / with_ray * 60:7.1f} trials/min ({with_ray:.1f} s); steady state "
                  f"{60 / ray_steady:7.1f} trials/min; vs 1 worker {one / with_ray:.2f}x overall, "
                  f"{one_steady / ray_steady:.2f}x steady\n")
    share, total, env_time, backend_time, steps = overhead_share(scenario, plugins)
    out.write(f"per step : {total / steps * 1000:.1f} ms total, simulator {env_time / steps * 1000:.1f} ms, "
              f"backend {backend_time / steps * 1000:.1f} ms, "
              f"framework {(total - env_time - backend_time) / steps * 1000:.1f} ms\n")
    out.write(f"framework overhead {share:.1%} of a step (target <= 10%)\n")


if __name__ == "__main__":
    main()
