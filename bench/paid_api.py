"""An ablation against a slow paid API, played by a stand-in: how many trials are in flight, how close
the calls come to the ideal rate, how long before the first call, and the memory and CPU it takes.

Run: ``python bench/paid_api.py [--latency 3.0] [--trials 16] [--max-steps 6] [--setting "--concurrency 16"]...
[--keep DIR]``

A fake OpenAI-compatible server on 127.0.0.1 (``tests/support/fake_openai.py``) answers every call
after ``--latency`` seconds with a valid plan; ``safeembodai ablate scenarios/<--scenario>.yaml``
(default ``mo``) with the ``gpt-4o`` backend runs against it once per ``--setting`` (default:
``--workers 1``, ``--concurrency 16``, ``--concurrency 64``, ``--workers 2 --concurrency 32``,
``--concurrency 128``), each in a fresh run folder with ``--no-cache`` (kept under ``--keep``).
Per setting it prints: trials, wall seconds, seconds to the first call,
the most calls in flight at once and their mean (sampled every 0.2 s from the first call to the
end, the tail included), the call rate between the first and the last call against the ideal (the
in-flight count the setting asks for / latency), the *steady* rate (between the call a quarter of
the way through and the one three quarters through: past the ramp while runners are built, before
the tail when fewer trials are left than slots) against the same ideal, the peak resident
memory of the run's processes (summed, read from /proc every 0.2 s), and the CPU per call over the
steady calls: the run's processes (coordinator and workers, user + system, from /proc) and this
one (the stand-in's parsing and answering, and the sampling).

**The workload's bound.** The ideal assumes every slot busy from the first call to the last. The
trials themselves may not allow it: with as many slots as trials nothing refills a slot whose trial
ended early, and the longest trial (a step asked again after a refusal is another call) sets the
whole run's length. ``workload_bound`` replays the run's own trials (the calls each made, read from
its store) with nothing but the model taking time, and the same two rates of that replay are
printed ("bound", of the ideal), then the measured rates as a share of them ("of bound": what our
own CPU and scheduling cost). Numbers, never asserts.
"""

from __future__ import annotations

import argparse
import os
import shlex
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path

import yaml

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO / "tests" / "support"))

from fake_openai import FakeOpenAI, Hang, Reply  # noqa: E402

from safeembodai_core.testing import answer, straight, turn  # noqa: E402

TIMELINE_S = 5.0
SETTINGS = ["--workers 1", "--concurrency 16", "--concurrency 64", "--workers 2 --concurrency 32",
            "--concurrency 128"]


def _answer(request) -> str:
    """A valid plan that varies with the prompt, so trials do not all do the same."""
    return answer(turn(25) if len(str(request.body.get("messages"))) % 3 == 0 else straight(150))


def _group_usage(pgid: int) -> tuple[float, float]:
    """The resident memory (MB) and the CPU seconds (user + system) of the processes in the group."""
    rss_kb, ticks = 0, 0
    for entry in Path("/proc").iterdir():
        if not entry.name.isdigit():
            continue
        try:
            stat = (entry / "stat").read_text().rsplit(")", 1)[1].split()
            if int(stat[2]) != pgid:
                continue
            ticks += int(stat[11]) + int(stat[12])
            for line in (entry / "status").read_text().splitlines():
                if line.startswith("VmRSS:"):
                    rss_kb += int(line.split()[1])
        except (OSError, ValueError, IndexError):
            continue
    return rss_kb / 1024, ticks / os.sysconf("SC_CLK_TCK")


def _cpu_at(samples: list[tuple[float, float, float]], moment: float) -> tuple[float, float]:
    """The run's and the stand-in's CPU seconds at ``moment``, interpolated between the samples."""
    if samples and moment < samples[0][0]:
        return samples[0][1], samples[0][2]
    for (t0, run0, own0), (t1, run1, own1) in zip(samples, samples[1:]):
        if t0 <= moment <= t1:
            share = (moment - t0) / (t1 - t0) if t1 > t0 else 0.0
            return run0 + share * (run1 - run0), own0 + share * (own1 - own0)
    return (samples[-1][1], samples[-1][2]) if samples else (float("nan"), float("nan"))


def _calls_per_trial(out: str, earlier: set[Path]) -> list[int]:
    """How many calls each trial of the run made (its steps' attempts), read from the store of the run
    folder it created under ``out`` (``earlier``: the folders there before it started)."""
    from safeembodai_plugins.state.sqlite_db import SqliteStateStore

    counts = []
    for store_path in sorted(set(Path(out).glob("*/results.sqlite")) - earlier):
        store = SqliteStateStore(store_path, readonly=True)
        try:
            for trial in store.trials():
                counts.append(sum(len(step.attempts) for step in store.iter_steps(trial["trial_id"])))
        finally:
            store.close()
    return counts


def _rates(stamps: list[float]) -> tuple[float, float]:
    """The call rate between the first and the last call, and the steady one: between the call a
    quarter of the way and the one three quarters of the way, past the start (runners still being
    built) and before the tail (fewer trials left than slots)."""
    calls = len(stamps)
    span = stamps[-1] - stamps[0] if calls > 1 else 0.0
    whole = (calls - 1) / span if span > 0 else float("nan")
    low, high = calls // 4, (3 * calls) // 4
    steady = (high - low) / (stamps[high] - stamps[low]) if calls >= 8 and stamps[high] > stamps[low] else float("nan")
    return whole, steady


def workload_bound(counts: list[int], slots: int, latency: float) -> tuple[float, float]:
    """The whole and steady rates the same trials would reach if nothing but the model took time:
    every call lasts ``latency``, a trial's calls follow each other at once, the slots open evenly
    over the first ``latency`` (no waves in step) and a slot takes the next trial the moment it is
    free (trials in the store's order). With as many slots as trials, the longest trial bounds the
    whole run, and trials that end early leave their slots empty. With fewer slots it is an estimate:
    the greedy order is not the scenario's dispatch order, nor the best one."""
    slots = max(1, slots)
    free = [k * latency / slots for k in range(slots)]
    stamps: list[float] = []
    for n in counts:
        slot = min(range(len(free)), key=free.__getitem__)
        start = free[slot]
        stamps.extend(start + k * latency for k in range(n))
        free[slot] = start + n * latency
    return _rates(sorted(stamps))


def _in_flight(setting: list[str]) -> int:
    values = {"--workers": 1, "--concurrency": 1}
    for flag, value in zip(setting, setting[1:]):
        if flag in values:
            values[flag] = int(value)
    return values["--workers"] * values["--concurrency"]


def run_setting(server: FakeOpenAI, scenario: Path, setting: list[str], latency: float,
                keep: Path | None = None) -> dict[str, float]:
    server.requests.clear()
    server.peak_in_flight = 0
    stamps: list[float] = []
    recorded = server.requests

    with tempfile.TemporaryDirectory(prefix="paid-api-") as scratch:
        out = str(keep / "-".join(setting).replace("--", "").replace(" ", "") if keep else scratch)
        earlier = set(Path(out).glob("*/results.sqlite"))
        started = time.monotonic()
        process = subprocess.Popen([sys.executable, "-m", "safeembodai_core", "ablate", str(scenario), "--out", out,
                                    "--no-report", "--no-cache", *setting], stdout=subprocess.DEVNULL,
                                   stderr=subprocess.PIPE, text=True, start_new_session=True,
                                   env={**os.environ, "SAFEEMBODAI_BENCH_KEY": "sk-bench-0000"})
        peak = 0.0
        seen = 0
        usage: list[tuple[float, float, float]] = []  # (time, the run's CPU s, the stand-in's CPU s)
        busy: list[int] = []  # calls in flight, sampled between the first and the last call
        while process.poll() is None:
            rss, cpu = _group_usage(process.pid)
            peak = max(peak, rss)
            usage.append((time.monotonic(), cpu, time.process_time()))
            if recorded:
                busy.append(server.in_flight)
            while seen < len(recorded):
                stamps.append(time.monotonic())
                seen += 1
            time.sleep(0.2)
        wall = time.monotonic() - started
        stderr = process.stderr.read() if process.stderr else ""
        if process.returncode != 0:
            raise SystemExit(f"{' '.join(setting)} failed ({process.returncode}): {stderr[-2000:]}")
        bound_whole, bound_steady = workload_bound(_calls_per_trial(out, earlier), _in_flight(setting), latency)
    while seen < len(recorded):
        stamps.append(time.monotonic())
        seen += 1
    calls = len(recorded)
    asked = _in_flight(setting)
    rate, steady = _rates(stamps)
    timeline = [0] * (int((stamps[-1] - started) // TIMELINE_S) + 1) if stamps else []
    for stamp in stamps:
        timeline[int((stamp - started) // TIMELINE_S)] += 1
    low, high = calls // 4, (3 * calls) // 4
    # CPU per call over the same middle half: the run's processes (coordinator and workers) and this
    # one (the stand-in's parsing and answering, and this sampling)
    run_low, own_low = _cpu_at(usage, stamps[low]) if calls >= 8 else (float("nan"),) * 2
    run_high, own_high = _cpu_at(usage, stamps[high]) if calls >= 8 else (float("nan"),) * 2
    per_call = 1000.0 / (high - low) if high > low else float("nan")
    return {"calls": calls, "wall_s": wall, "timeline": timeline, "steady": steady,
            "first_call_s": stamps[0] - started if stamps else float("nan"),
            "peak_in_flight": server.peak_in_flight, "asked": asked, "rate": rate,
            "mean_in_flight": sum(busy) / len(busy) if busy else float("nan"),
            "ideal": asked / latency, "peak_mb": peak, "run_cpu_ms": (run_high - run_low) * per_call,
            "stand_in_cpu_ms": (own_high - own_low) * per_call,
            "bound_whole": bound_whole, "bound_steady": bound_steady}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--latency", type=float, default=3.0, help="seconds before the stand-in answers")
    parser.add_argument("--scenario", default="mo", help="a shipped scenario (mo: Labbots move while the robot "
                                                           "thinks, which costs CPU; of: static obstacles)")
    parser.add_argument("--trials", type=int, default=16, help="trials per cell (the shipped scenarios have 4 cells)")
    parser.add_argument("--max-steps", type=int, default=6)
    parser.add_argument("--setting", action="append", help="ablate options to measure (repeatable)")
    parser.add_argument("--keep", type=Path, help="keep each setting's run folder under this folder")
    parser.add_argument("--timeline", action="store_true",
                        help=f"also print the calls made in each {TIMELINE_S:g} s from the start")
    args = parser.parse_args()
    with FakeOpenAI(Hang(args.latency, then=Reply(_answer))) as server, \
            tempfile.TemporaryDirectory(prefix="paid-api-scenario-") as folder:
        data = yaml.safe_load((REPO / "scenarios" / f"{args.scenario}.yaml").read_text())
        options = {"api_base": server.url, "api_key_env": "SAFEEMBODAI_BENCH_KEY", "timeout_s": args.latency + 30}
        data.update(trials=args.trials, max_steps=args.max_steps, backend={"use": "gpt-4o", "options": options})
        scenario = Path(folder) / f"{args.scenario}.yaml"
        scenario.write_text(yaml.safe_dump(data))
        print(f"{args.scenario}.yaml, {args.trials} trials per cell of at most {args.max_steps} steps, every call "
              f"answered after {args.latency:g} s; {os.cpu_count()} cores")
        print(f"{'setting':32} {'calls':>6} {'wall s':>7} {'first call s':>12} {'peak/asked':>10} "
              f"{'mean':>6} {'calls/s':>8} {'ideal':>6} {'of ideal':>8} {'steady':>7} {'of ideal':>8} {'peak MB':>8} "
              f"{'CPU ms/call':>11} {'stand-in':>8} {'bound whole':>11} {'steady':>6} {'of bound':>8} {'steady':>6}")
        for setting in args.setting or SETTINGS:
            row = run_setting(server, scenario, shlex.split(setting), args.latency, args.keep)
            threading.Event().wait(1.0)  # let the stand-in's sockets settle between runs
            print(f"{setting:32} {row['calls']:>6} {row['wall_s']:>7.1f} {row['first_call_s']:>12.1f} "
                  f"{row['peak_in_flight']:>4}/{row['asked']:<5} {row['mean_in_flight']:>6.1f} "
                  f"{row['rate']:>8.2f} {row['ideal']:>6.2f} "
                  f"{row['rate'] / row['ideal']:>8.0%} {row['steady']:>7.2f} {row['steady'] / row['ideal']:>8.0%} "
                  f"{row['peak_mb']:>8.0f} {row['run_cpu_ms']:>11.1f} {row['stand_in_cpu_ms']:>8.1f} "
                  f"{row['bound_whole'] / row['ideal']:>8.0%} {row['bound_steady'] / row['ideal']:>8.0%} "
                  f"{row['rate'] / row['bound_whole']:>6.0%} {row['steady'] / row['bound_steady']:>6.0%}", flush=True)
            if args.timeline:
                print(f"  calls per {TIMELINE_S:g} s: {' '.join(str(n) for n in row['timeline'])}", flush=True)


if __name__ == "__main__":
    main()
