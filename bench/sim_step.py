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


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--kind", default="MO", choices=["OF", "SO", "DO", "MO"])
    parser.add_argument("--steps", type=int, default=40, help="repetitions per measurement")
    parser.add_argument("--envs", type=int, default=4, help="environments created for the memory figure")
    parser.add_argument("--seed", type=int, default=3)
    args = parser.parse_args()

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
