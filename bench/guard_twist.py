"""What the robot guard costs: a held Twist judged, a speed limit, and a live node's loop.

1. ``Guard().check_twist`` (robot defaults: ``command_limits`` + ``swept_body``) on a 1,081-beam
   scan (270 degrees, 0.25 degree steps, a corridor with a post) and a 2 s hold: milliseconds per
   check, disc and polygon footprint, straight, arc and turn in place; and the paper's rules on the
   same for comparison.
2. ``Guard().limit_twist`` on the same: milliseconds per call.
3. ``CommandFilter`` fed 40 Hz scans and 20 Hz commands for ``--seconds`` of simulated time: the
   CPU time it takes, as a share of one core over that span.

    python bench/guard_twist.py [--repeat 200] [--seconds 20]

One core: run it with nothing else busy (or under ``taskset -c 0``); each figure is the median of
``--repeat`` calls after a warm-up.
"""

from __future__ import annotations

import argparse
import math
import statistics
import time
from types import SimpleNamespace


def corridor_scan(beams: int = 1081):
    """A 270-degree scanner in a 1.2 m wide corridor, a post 0.8 m ahead and 0.35 m to the left."""
    from safeembodai_core.ros import LaserScan

    angle_min, inc = -math.radians(135), math.radians(0.25)
    ranges = []
    for k in range(beams):
        a = angle_min + k * inc
        s, c = math.sin(a), math.cos(a)
        wall = 0.6 / abs(s) if abs(s) > 1e-6 else math.inf
        hit = min(wall, 8.0 if c > 0 else wall)
        # the post: a 0.1 m disc at (0.8, 0.35)
        b = 0.8 * c + 0.35 * s
        d2 = b * b - (0.8 ** 2 + 0.35 ** 2 - 0.05 ** 2)
        if d2 >= 0 and b > 0:
            hit = min(hit, b - math.sqrt(d2))
        ranges.append(hit if hit <= 8.0 else math.inf)
    return LaserScan.from_ros(SimpleNamespace(angle_min=angle_min, angle_increment=inc, range_min=0.05,
                                              range_max=8.0, ranges=ranges))


def median_ms(call, repeat: int) -> float:
    for _ in range(5):
        call()
    times = []
    for _ in range(repeat):
        started = time.perf_counter()
        call()
        times.append(time.perf_counter() - started)
    return statistics.median(times) * 1000.0


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeat", type=int, default=200)
    parser.add_argument("--seconds", type=float, default=20.0)
    args = parser.parse_args()

    from safeembodai_core import Guard, RobotSpec
    from safeembodai_core.ros import CommandFilter, Twist

    scan = corridor_scan()
    lidar = scan.to_lidar_scan()
    polygon = RobotSpec(radius_mm=320, footprint_mm=[(300, 170), (-200, 170), (-200, -170), (300, -170)])
    guards = {"disc": Guard(), "polygon": Guard(robot=polygon)}
    twists = {"straight": Twist(0.3, 0.0), "arc": Twist(0.3, 0.4), "turn": Twist(0.0, 0.8)}
    print(f"scan: {len(scan.ranges)} beams -> {lidar.beam_count} bins; hold 2 s")
    print(f"{'body':8} {'twist':9} {'check_twist ms':>15} {'limit_twist ms':>15} {'paper rules ms':>15}")
    paper = Guard(["command_limits", "lidar_clearance"])
    for body, guard in guards.items():
        for name, twist in twists.items():
            check = median_ms(lambda: guard.check_twist(twist, 2.0, lidar_mm=lidar), args.repeat)
            limit = median_ms(lambda: guard.limit_twist(twist, 2.0, lidar_mm=lidar), args.repeat)
            vc = (median_ms(lambda: paper.check_twist(twist, 2.0, lidar_mm=lidar), args.repeat) if body == "disc"
                  else math.nan)
            print(f"{body:8} {name:9} {check:15.3f} {limit:15.3f} {vc:15.3f}")

    node = CommandFilter(Guard(), horizon_s=1.0, scan_timeout_s=0.3)
    message = SimpleNamespace(angle_min=scan.angle_min, angle_increment=scan.angle_increment, range_min=0.05,
                              range_max=8.0, ranges=list(scan.ranges))
    events = sorted([(k / 40.0, "scan") for k in range(int(args.seconds * 40))]
                    + [(k / 20.0 + 0.001, "cmd") for k in range(int(args.seconds * 20))])
    started = time.process_time()
    for t, kind in events:
        if kind == "scan":
            node.on_scan(message, t)
        else:
            node.on_command(Twist(0.3, 0.2), t)
    cpu = time.process_time() - started
    print(f"node loop: {args.seconds:g} s of 40 Hz scans + 20 Hz commands in {cpu:.2f} s of CPU = "
          f"{100 * cpu / args.seconds:.1f}% of one core")


if __name__ == "__main__":
    main()
