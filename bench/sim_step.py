"""Per-step cost of the pybullet rooms, broken down, and memory per environment.

Run: ``python bench/sim_step.py [--kind MO] [--steps 40] [--envs 4]``. Prints milliseconds per
call for each part (median over ``--steps`` repetitions, same process, same room):

* ray cast: one ``rayTestBatch`` of the LiDAR beams, straight into pybullet;
* camera render: one TinyRenderer image at the camera size, straight into pybullet;
* collision checks: ``performCollisionDetection`` + ``getContactPoints`` once per increment of a
  300 mm straight (what kinematic motion cannot avoid), with the robot re-posed each time;
* LiDAR image: the ``images`` perception drawing and encoding the top-down LiDAR map;
* observe / 300 mm straight: the environment's own calls;
* full control step: ``observe()`` + one 300 mm ``straight`` + ``outcome()``.

and the ratio of the full step to the sum of its unavoidable parts (ray cast + render +
collision checks; target at most 1.3x), then the resident memory each extra environment adds
(target under 150 MB). Numbers, never asserts: run it on a quiet machine.

``--loop SCENARIO`` (``mo``, ``of``, any shipped scenario or a path) measures instead the core loop's
step as an ablation runs it (issue 51): the scenario's trials with its own backend (the shipped
ones: the mock pilot, no LLM latency) and its sqlite store in a scratch folder, one process, after a
warm-up trial, cells taken in turn, until ``--steps`` steps are done. A step runs from its
observation (the reset's for step 1) to the next one (or the trial's end): the think time, the
commands, perception, prompt, the pilot, validation and the records. Printed: CPU milliseconds per
step (``time.process_time``; median, mean, 90th percentile), the environment's share of them
(observe, sense, execute, outcome) and the mean CPU per step of its parts timed alike (the camera,
the LiDAR, the think time, the commands) and of the rest. ``--profile FILE`` also writes a
cProfile of the measured trials (its overhead weighs on Python calls far more than on pybullet's).
"""

from __future__ import annotations

import argparse
import gc
import math
import statistics
import time

import numpy as np

from safeembodai_core.models import Straight, Turn
from safeembodai_core.plugin.manager import load_plugins

STRAIGHT = Straight(command="straight", direction="forward", distance=300.0)
BACK = Straight(command="straight", direction="backward", distance=300.0)


def rss_mb() -> float:
    """Resident set size of this process in MB (Linux /proc; ru_maxrss elsewhere)."""
    try:
        with open("/proc/self/statm") as handle:
            pages = int(handle.read().split()[1])
        import os

        return pages * os.sysconf("SC_PAGE_SIZE") / 2**20
    except OSError:
        import resource

        return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024


def measure(functions: dict, repeats: int) -> dict:
    """Median milliseconds per call of each function, timed round-robin so load drifts hit all alike."""
    for function in functions.values():
        function()  # warm-up
    samples: dict = {name: [] for name in functions}
    for _ in range(repeats):
        for name, function in functions.items():
            start = time.perf_counter()
            function()
            samples[name].append((time.perf_counter() - start) * 1000.0)
    return {name: statistics.median(values) for name, values in samples.items()}


def free_pose(env) -> None:
    """Turn the robot toward its longest free direction so a 300 mm straight never touches anything."""
    scan = env.observe().lidar
    best = int(np.nanargmax(np.where(np.isinf(scan.ranges_mm), scan.max_range_mm, scan.ranges_mm)))
    angle = float(scan.angles_deg[best])
    while abs(angle) > 0.5:
        step = math.copysign(min(abs(angle), 89.0), angle)
        env.execute(Turn(command="turn", direction="left" if step > 0 else "right", angle=abs(step)))
        angle -= step


def loop_steps(scenario_path: str, steps: int, profile: str | None) -> None:
    """CPU milliseconds per step of the scenario's trials, as an ablation runs them (see the module doc)."""
    import cProfile
    import tempfile
    from pathlib import Path

    from safeembodai_core.runs.runner import ScenarioRunner
    from safeembodai_core.scenario.loader import load_scenario

    path = Path(scenario_path)
    if not path.exists():
        path = Path(__file__).resolve().parents[1] / "scenarios" / f"{scenario_path}.yaml"
    plugins = load_plugins()
    cells = len(load_scenario(path, [], plugins.registry).cells())
    trials = max(2, steps // (5 * cells) + 2)  # trials per cell: enough for the steps asked, with room to spare
    scenario = load_scenario(path, [f"trials={trials}"], plugins.registry)
    clock = time.process_time
    with tempfile.TemporaryDirectory(prefix="sim-step-") as folder:
        runner = ScenarioRunner(scenario, plugins, run_dir=folder)
        specs = sorted(runner.specs(), key=lambda spec: (spec.index, spec.trial_id))  # cells in turn
        runner.run(specs[0])  # warm-up: imports, tokenizer, the room built
        starts: list[float] = []
        in_env = [0.0, 0]  # seconds in the environment's calls, calls open (reset observes inside itself)
        env = runner.environment(specs[0].environment)

        def timed(method, marks: bool):
            def call(*args, **kwargs):
                begin = clock()
                if marks and not in_env[1]:
                    starts.append(begin)
                in_env[1] += 1
                try:
                    return method(*args, **kwargs)
                finally:
                    in_env[1] -= 1
                    if not in_env[1]:
                        in_env[0] += clock() - begin
            return call

        # a step starts at its observation (reset's for step 1); the environment's own calls are summed
        env.reset, env.observe = timed(env.reset, True), timed(env.observe, True)
        for name in ("execute", "outcome", "sense"):
            if hasattr(env, name):
                setattr(env, name, timed(getattr(env, name), False))
        parts = {"camera": 0.0, "LiDAR": 0.0, "think time (Labbots while the robot stands)": 0.0,
                 "commands (robot and Labbots)": 0.0}

        def part(owner, name: str, label: str) -> None:  # the parts of the room's work, timed alike
            method = getattr(owner, name, None)
            if method is None:
                return

            def call(*args, **kwargs):
                begin = clock()
                try:
                    return method(*args, **kwargs)
                finally:
                    parts[label] += clock() - begin
            setattr(owner, name, call)

        sensors = getattr(env, "sensors", None)
        part(sensors, "camera", "camera")
        part(sensors, "lidar", "LiDAR")
        part(env, "_wait", "think time (Labbots while the robot stands)")
        part(env, "_move", "commands (robot and Labbots)")
        per_step: list[float] = []
        env_s = total_s = 0.0
        profiler = cProfile.Profile() if profile else None
        shares: dict[str, float] = {}
        ran = 0
        for spec in specs[1:]:
            if len(per_step) >= steps:
                break
            ran += 1
            starts.clear()
            in_env[0] = 0.0
            before = dict(parts)
            if profiler:
                profiler.enable()
            runner.run(spec)
            end = clock()
            if profiler:
                profiler.disable()
            marks = list(starts)
            per_step += [b - a for a, b in zip(marks, marks[1:] + [end])]
            spent = {label: parts[label] - before[label] for label in parts}
            for label, seconds in spent.items():
                shares[label] = shares.get(label, 0.0) + seconds
            env_s += in_env[0]
            total_s += end - marks[0]
        runner.close()
    if profiler and profile:
        profiler.dump_stats(profile)
    ms = sorted(1000.0 * value for value in per_step)
    n = len(ms)
    print(f"{path.name}: {n} steps in {ran} trials (backend as the scenario gives it), CPU ms per step: "
          f"median {statistics.median(ms):.1f}, mean {statistics.fmean(ms):.1f}, p90 {ms[int(0.9 * (n - 1))]:.1f}; "
          f"environment {100.0 * env_s / total_s:.0f}% of it")
    print("  mean CPU ms per step: " + ", ".join(f"{label} {1000.0 * seconds / n:.1f}"
                                                 for label, seconds in shares.items())
          + f", the rest {1000.0 * (total_s - sum(shares.values())) / n:.1f} (pilot, perception, prompt, records)")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--loop", metavar="SCENARIO", help="measure the core loop's step over a scenario's trials")
    parser.add_argument("--profile", metavar="FILE", help="with --loop: write a cProfile of the measured trials")
    parser.add_argument("--kind", default="MO", choices=["OF", "SO", "DO", "MO"])
    parser.add_argument("--steps", type=int, default=40, help="repetitions per measurement")
    parser.add_argument("--envs", type=int, default=4, help="environments created for the memory figure")
    parser.add_argument("--seed", type=int, default=3)
    args = parser.parse_args()
    if args.loop:
        loop_steps(args.loop, args.steps, args.profile)
        return

    registry = load_plugins(environ={}).registry
    perception = registry.build("perception", "images", {})
    env = registry.build("environment", args.kind, {"max_sim_time_s": 1e5})
    env.reset(args.seed)
    free_pose(env)  # every part is measured from this pose, facing the clearest way
    check = env.execute(STRAIGHT)
    env.execute(BACK)
    if check.stopped:
        print(f"warning: the timed straight was cut short ({check.detail}); try another --seed")
    scene, sensors, o = env.scene, env.sensors, env.options
    p, client = scene.p, scene.client
    xy, heading = env.xy.copy(), env.heading

    angles = sensors.beam_angles + math.radians(heading)
    start = [[xy[0] / 1000, xy[1] / 1000, 0.1]] * o.lidar_beams
    end = [[xy[0] / 1000 + 6 * math.cos(a), xy[1] / 1000 + 6 * math.sin(a), 0.1] for a in angles]
    eye, forward = sensors.camera_pose(xy, heading)
    view = p.computeViewMatrix(eye.tolist(), (eye + forward).tolist(), (0, 0, 1), physicsClientId=client)
    increments = math.ceil(STRAIGHT.distance / o.step_mm)

    flush = getattr(scene, "flush", lambda: None)  # placements reach Bullet at its next read (none before issue 51)
    flush()  # these parts read Bullet directly

    def ray_cast():
        p.rayTestBatch(start, end, numThreads=1, physicsClientId=client)

    def render():
        p.getCameraImage(o.camera_width, o.camera_height, view, sensors.projection, shadow=0,
                         renderer=p.ER_TINY_RENDERER, flags=p.ER_NO_SEGMENTATION_MASK, physicsClientId=client)

    def collision_checks():
        rad = math.radians(heading)
        for k in range(increments):
            position = (xy[0] / 1000 + k * 0.01 * math.cos(rad), xy[1] / 1000 + k * 0.01 * math.sin(rad), 0.1)
            p.resetBasePositionAndOrientation(scene.robot, position, (0, 0, 0, 1), physicsClientId=client)
            p.performCollisionDetection(physicsClientId=client)
            p.getContactPoints(bodyA=scene.robot, physicsClientId=client)
        scene.place_robot(env.xy, env.heading)
        flush()

    observation = env.observe()

    def lidar_image():
        perception.perceive(observation)


    def straight_there_and_back():
        env.execute(STRAIGHT)
        env.execute(BACK)

    def full_step():
        env.observe()
        env.execute(STRAIGHT)
        env.outcome()
        env.execute(BACK)  # back to where it was, so every repetition drives the same free line

    times = measure({
        "ray": ray_cast, "render": render, "collisions": collision_checks, "lidar_image": lidar_image,
        "observe": env.observe, "straight": straight_there_and_back, "full": full_step,
    }, args.steps)
    straight_ms = times["straight"] / 2
    full_ms = times["full"] - straight_ms  # minus the drive back
    parts = {
        "ray cast (rayTestBatch, %d beams)" % o.lidar_beams: times["ray"],
        "camera render (%dx%d TinyRenderer)" % (o.camera_width, o.camera_height): times["render"],
        "collision checks (%d increments)" % increments: times["collisions"],
    }
    lidar_ms, observe_ms, n = times["lidar_image"], times["observe"], args.steps
    unavoidable = sum(parts.values())

    print(f"pybullet room {args.kind}, seed {args.seed}, median of {n} (milliseconds per call)")
    for name, value in parts.items():
        print(f"  {name:<44} {value:8.3f}")
    print(f"  {'LiDAR image (images perception, PNG)':<44} {lidar_ms:8.3f}")
    print(f"  {'observe() (LiDAR + camera + ground truth)':<44} {observe_ms:8.3f}")
    print(f"  {'execute(straight 300 mm)':<44} {straight_ms:8.3f}")
    print(f"  {'full control step (observe+straight+outcome)':<44} {full_ms:8.3f}")
    print(f"  {'sum of unavoidable parts':<44} {unavoidable:8.3f}")
    print(f"ratio full step / unavoidable parts: {full_ms / unavoidable:.2f}x (target <= 1.3x)")
    print(f"full step with the LiDAR image: {full_ms + lidar_ms:.3f} ms")
    env.close()

    gc.collect()
    before = rss_mb()
    envs = []
    for index in range(args.envs):
        extra = registry.build("environment", args.kind, {})
        extra.reset(index)
        extra.observe()
        envs.append(extra)
    gc.collect()
    per_env = (rss_mb() - before) / args.envs
    print(f"memory: {per_env:.1f} MB per {args.kind} environment ({args.envs} created; target < 150 MB); "
          f"process RSS {rss_mb():.0f} MB")
    for extra in envs:
        extra.close()


if __name__ == "__main__":
    main()
