"""What serve-robot and guard-node cost on the wire, against issue 48's bars.

    python bench/live_wire.py serve  [--seconds 30] [--warmup 5]   # serve-robot on one core
    python bench/live_wire.py decide [--repeat 1000]                # guard-node's decision, in process
    python bench/live_wire.py guard  [--seconds 20] [--warmup 3]   # guard-node on the wire, on one core
    python bench/live_wire.py all [--profile]                       # the three, about two minutes

``serve``: ``safeembodai serve-robot scenarios/mo.yaml`` run by its CLI under ``taskset -c CORE``,
with its default rates (``/scan`` 10 Hz, ``/odom`` 20 Hz, the camera 5 Hz); this process (kept off
that core) subscribes to the three, so each is encoded and sent, and publishes ``/cmd_vel`` at 20 Hz
(back and forth, turning, every command a distinct ``angular.z``). Over the window after the warm-up:

* the real-time factor: the least-squares slope of the room's time (``/odom`` header stamps) on the
  wall time they arrived at, whole and per 5 s; how late each ``/odom`` arrived after its room time
  (a room falling behind the wall clock would show as a growing lateness); the rate each stream reached;
* the served process's CPU (``/proc/PID/stat`` utime + stime over the window) and peak RSS (VmHWM);
* a command's latency, publish to the room applying it. The room takes a command at a time of its
  own clock, which the session's record keeps (each step's ``sim_time_s``); the room's clock starts
  at a ``time.monotonic()`` of the served process, the same clock as ours on Linux, found as the
  smallest (arrival - stamp) over every ``/odom`` (an over-estimate by the quickest odometry's
  delivery, so the latency is over-estimated by as much). Check from outside: the first ``/odom``
  whose twist carries a command's ``angular.z`` was published when the room already held it, so
  its stamp must come at or after the record's time (counted), and its arrival bounds the command's
  visible effect from above (one ``/odom`` period of 50 ms on top of the latency). A client's
  ``std_msgs/String`` ping to itself through the served process gives the wire's round trip beside it.

``decide``: :class:`~safeembodai_core.guard_node.node.GuardNode` built as the CLI builds it, fed
rosbridge's own JSON (a 360- and a 720-beam LaserScan of a 6 x 4 m room with a post ahead, an open
door behind and 3% dropouts, all ``null`` on the wire; Odometry at 20 Hz; a mix of commands held 1 s
each): milliseconds per ``on_scan`` (reading the dict), ``on_odom``, ``on_command`` (the smoother and
the decision), and for the frame reader that the client runs on each scan before the node sees it;
for the 170 mm disc and the example's footprint reading ``null`` as no return, and the disc with the
CLI's default reading (``unknown``: a dropout is space the scan did not see).

``guard``: ``safeembodai guard-node`` by its CLI under ``taskset -c CORE``, once with a 170 mm disc
(the CLI's default body) and once with the example robot file's 4-vertex footprint and scanner mount
(``docs/examples/robot.yaml``), both reading ``null`` as no return, against a
:class:`~safeembodai_core.rosbridge.server.RosbridgeServer` in this process serving ``/scan`` (360
beams) at 40 Hz and ``/odom`` at 20 Hz, while a client publishes ``/cmd_vel_in`` at 20 Hz: its CPU
share over the window (and per second) and peak RSS, and what it sent.

Before guard-node, the same traffic through a bare ``RosbridgeClient`` that relays each command and
repeats it at 20 Hz with no guard (``WIRE_ALONE``): the floor that the wire itself costs, for the ratio.

``--profile`` samples the measured process with ``py-spy record`` over the window (on the path, or
``--py-spy PATH``) and prints its costliest functions; py-spy pauses the process at each sample, which
adds to its CPU share (guard-node 12.5% -> 16.9%) and its latencies: take the figures from a run
without it. CPU shares come from ``/proc``: they hold under other load better than the wall-clock
figures (the latencies); the header line gives the load average.

Numbers, never asserts. Bars (issue 48): RTF >= 1.0, memory <= 300 MB per process, a command
applied within 20 ms (median), a decision within 5 ms (median), guard-node <= 10% of a core.
"""

from __future__ import annotations

import argparse
import atexit
import datetime
import json
import math
import os
import re
import shutil
import signal
import statistics
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
CLI = str(Path(sys.executable).with_name("safeembodai"))
TWIST, STRING = "geometry_msgs/msg/Twist", "std_msgs/msg/String"
LASER_SCAN, ODOMETRY = "sensor_msgs/msg/LaserScan", "nav_msgs/msg/Odometry"
CAMERA = "/camera/image_raw/compressed"


# -- figures and processes ---------------------------------------------------------------------------

def quantile(values: list[float], q: float) -> float:
    ordered = sorted(values)
    return ordered[min(len(ordered) - 1, max(0, math.ceil(q * len(ordered)) - 1))]


def spread(values: list[float], unit: str = "", digits: int = 2) -> str:
    """``median (p10-p90, max; N)`` of ``values``."""
    if not values:
        return "no samples"
    f = f"{{:.{digits}f}}"
    return (f"median {f.format(statistics.median(values))}{unit} (p10 {f.format(quantile(values, 0.1))}, "
            f"p90 {f.format(quantile(values, 0.9))}, max {f.format(max(values))}; N={len(values)})")


def short(values: list[float]) -> str:
    """``median (p90 x, p99 y)`` in milliseconds."""
    return f"{statistics.median(values):.3f} (p90 {quantile(values, 0.9):.3f}, p99 {quantile(values, 0.99):.2f})"


def slope(points: list[tuple[float, float]]) -> float:
    """Least-squares slope of y on x."""
    mx = statistics.fmean(x for x, _ in points)
    my = statistics.fmean(y for _, y in points)
    return (sum((x - mx) * (y - my) for x, y in points) / sum((x - mx) ** 2 for x, _ in points))


def cpu_seconds(pid: int) -> float:
    """utime + stime of process ``pid``, all its threads (``/proc/PID/stat``)."""
    fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")


def memory_mb(pid: int) -> dict[str, float]:
    """VmHWM (peak RSS) and VmRSS of ``pid`` in MB."""
    values = {}
    for line in Path(f"/proc/{pid}/status").read_text().splitlines():
        key = line.split(":", 1)[0]
        if key in ("VmHWM", "VmRSS"):
            values[key] = int(line.split()[1]) / 1024
    return values


def keep_off(core: int) -> None:
    """Run this process on the cores other than ``core`` (the measured process has that one)."""
    others = os.sched_getaffinity(0) - {core}
    if others:
        os.sched_setaffinity(0, others)


def conditions() -> str:
    commit = subprocess.run(["git", "rev-parse", "--short", "HEAD"], cwd=ROOT, capture_output=True, text=True)
    dirty = subprocess.run(["git", "status", "--porcelain", "--untracked-files=no"], cwd=ROOT, capture_output=True,
                           text=True).stdout.strip()
    return (f"commit {commit.stdout.strip() or '?'}{' + uncommitted changes' if dirty else ''}; "
            f"{datetime.datetime.now().isoformat(timespec='minutes')}; {os.cpu_count()} cores; "
            f"load {Path('/proc/loadavg').read_text().split()[:3]}; Python {sys.version.split()[0]}")


class Cli:
    """A ``safeembodai`` command (or a Python one: ``args`` starting with ``sys.executable``) on one
    core, its output read until ``ready`` appears, then drained."""

    def __init__(self, core: int, args: list[str], ready: str, timeout: float = 60.0) -> None:
        env = {**os.environ, "COLUMNS": "400", "NO_COLOR": "1"}
        argv = args if args[0] == sys.executable else [CLI, *args]
        self.process = subprocess.Popen(["taskset", "-c", str(core), *argv], cwd=ROOT, env=env, text=True,
                                        stdout=subprocess.PIPE, stderr=subprocess.STDOUT)
        atexit.register(self.end)  # never leave it running when this script fails
        self.lines: list[str] = []
        deadline = time.monotonic() + timeout
        assert self.process.stdout is not None
        for line in self.process.stdout:
            self.lines.append(line.rstrip())
            if re.search(ready, line):
                self.ready = line
                break
            if time.monotonic() > deadline:
                raise RuntimeError(f"not ready after {timeout:g} s:\n" + "\n".join(self.lines[-20:]))
        else:
            raise RuntimeError("the command ended before it was ready:\n" + "\n".join(self.lines[-20:]))
        threading.Thread(target=self._drain, daemon=True).start()

    @property
    def pid(self) -> int:
        return self.process.pid

    def _drain(self) -> None:
        assert self.process.stdout is not None
        for line in self.process.stdout:
            self.lines.append(line.rstrip())

    def end(self) -> int:
        """SIGINT (the commands' clean ending), then a kill after 30 s; the exit status."""
        if self.process.poll() is not None:
            return self.process.returncode
        self.process.send_signal(signal.SIGINT)
        try:
            return self.process.wait(30)
        except subprocess.TimeoutExpired:
            self.process.kill()
            return self.process.wait()


class Window:
    """CPU and wall time of a process over a window, and per :meth:`tick` (about a second each)."""

    def __init__(self, pid: int) -> None:
        self.pid = pid
        self.marks = [(time.monotonic(), cpu_seconds(pid))]

    def tick(self) -> None:
        self.marks.append((time.monotonic(), cpu_seconds(self.pid)))

    def close(self) -> tuple[float, float, list[float]]:
        """(wall seconds, CPU share of one core, the share between each tick)."""
        self.tick()
        (wall0, cpu0), (wall1, cpu1) = self.marks[0], self.marks[-1]
        shares = [(c1 - c0) / (w1 - w0) for (w0, c0), (w1, c1) in zip(self.marks, self.marks[1:])]
        return wall1 - wall0, (cpu1 - cpu0) / (wall1 - wall0), shares


#: Leaf functions that wait (py-spy --nonblocking cannot always tell an idle thread): left out.
IDLE = re.compile(r"^(?:\w+\.)*(select|wait|_worker|sleep|poll) \(")


class Profile:
    """``py-spy record`` of ``pid`` over ``seconds`` (not pausing it: ``--nonblocking``), then its top costs."""

    def __init__(self, spy: str | None, pid: int, seconds: float) -> None:
        self.output = Path(tempfile.mkdtemp(prefix="live_wire_") if spy else ".") / "stacks.txt"
        self.process = None if not spy else subprocess.Popen(
            [spy, "record", "--pid", str(pid), "--duration", str(max(1, int(seconds))), "--rate", "200",
             "--format", "raw", "--output", str(self.output)],
            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)

    def report(self, top: int = 12) -> None:
        if self.process is None:
            return
        self.process.wait(60)
        if not self.output.exists():
            print("  (py-spy recorded nothing: may it attach? see ptrace_scope)")
            return
        inclusive: dict[str, int] = {}
        leaf: dict[str, int] = {}
        ours: set[str] = set()
        total = 0
        text = self.output.read_text()
        shutil.rmtree(self.output.parent, ignore_errors=True)
        for line in text.splitlines():
            stack, _, count = line.rpartition(" ")
            frames = [frame for frame in stack.split(";") if frame]
            names = [re.sub(r" \((.*?)(?::\d+)?\)$", lambda m: f" ({'/'.join(m.group(1).split('/')[-2:])})", frame)
                     for frame in frames]
            if not names or IDLE.match(names[-1]):
                continue
            n = int(count)
            total += n
            for name in set(names):
                inclusive[name] = inclusive.get(name, 0) + n
            leaf[names[-1]] = leaf.get(names[-1], 0) + n
            ours.update(name for frame, name in zip(frames, names)
                        if re.search(r"[ (/](safeembodai_core|plugins)/", frame) and "/cli/" not in frame)
        if not total:
            print("  py-spy: no busy samples")
            return
        print(f"  py-spy: {total} samples at 200 Hz of the process's threads, waits left out "
              f"({total / 200:.1f} s of a core); the costliest:")
        print("    with what they call: " + "; ".join(f"{name} {100 * inclusive[name] / total:.0f}%" for name in sorted(
            ours, key=lambda name: -inclusive[name])[:top]))
        print("    themselves: " + "; ".join(f"{name} {100 * n / total:.0f}%" for name, n in sorted(
            leaf.items(), key=lambda item: -item[1])[:top]))


def stamp_s(message: dict) -> float:
    stamp = message["header"]["stamp"]
    return stamp["sec"] + stamp["nanosec"] * 1e-9


# -- serve-robot ---------------------------------------------------------------------------------------

def command(k: int) -> tuple[float, float]:
    """The ``k``-th command: 0.1 m/s forward then back every 0.5 s, turning, ``angular.z`` distinct over
    200 commands (to read which command an ``/odom`` carries)."""
    sign = 1.0 if (k // 10) % 2 == 0 else -1.0
    return 0.1 * sign, sign * round(0.4 + 0.001 * (k % 200), 3)


def serve(args: argparse.Namespace) -> None:
    from safeembodai_core.rosbridge.client import RosbridgeClient

    keep_off(args.core)
    print(f"== serve-robot scenarios/mo.yaml on core {args.core} ({conditions()})")
    out = tempfile.mkdtemp(prefix="live_wire_")
    cli = Cli(args.core, ["serve-robot", "scenarios/mo.yaml", "--port", "0", "--out", out, "--speed", str(args.speed)],
              r"^serving .* at ws://")
    port = int(re.search(r"ws://[\d.]+:(\d+)", cli.ready).group(1))
    folder = re.search(r"recording to (\S+);", cli.ready).group(1)
    received: dict[str, list] = {"/scan": [], "/odom": [], CAMERA: [], "ping": []}
    sizes: dict[str, int] = {}

    def keep(topic: str):
        def on_message(message: dict) -> None:
            now = time.monotonic()
            twist = message.get("twist", {}).get("twist", {})
            received[topic].append((now, stamp_s(message), twist.get("angular", {}).get("z")))
            if topic not in sizes:
                sizes[topic] = len(json.dumps(message))
        return on_message

    client = RosbridgeClient(f"ws://127.0.0.1:{port}").connect()
    client.subscribe("/scan", LASER_SCAN, keep("/scan"))
    client.subscribe("/odom", ODOMETRY, keep("/odom"))
    client.subscribe(CAMERA, "sensor_msgs/msg/CompressedImage", keep(CAMERA))
    client.advertise("/cmd_vel", TWIST)
    client.advertise("/bench/ping", STRING)
    pings: dict[int, float] = {}
    client.subscribe("/bench/ping", STRING,
                     lambda m: received["ping"].append(time.monotonic() - pings[int(m["data"])]))
    period = 0.05
    total = int((args.warmup + args.seconds) / period)
    published: list[float] = []
    started = time.monotonic()
    window = profile = None
    for k in range(total):
        at = started + k * period
        time.sleep(max(0.0, at - time.monotonic()))
        if k == int(args.warmup / period):
            window, profile = Window(cli.pid), Profile(args.py_spy, cli.pid, args.seconds)
        elif window is not None and k % 20 == 0:
            window.tick()
        linear, angular = command(k)
        published.append(time.monotonic())
        client.publish("/cmd_vel", {"linear": {"x": linear, "y": 0.0, "z": 0.0},
                                    "angular": {"x": 0.0, "y": 0.0, "z": angular}})
        if k % 4 == 2:
            pings[k] = time.monotonic()
            client.publish("/bench/ping", {"data": str(k)})
    time.sleep(0.3)
    assert window is not None and profile is not None
    wall, share, seconds = window.close()
    memory = memory_mb(cli.pid)
    client.close()
    cli.end()
    window_start = started + args.warmup

    # the room's time against ours
    odoms = received["/odom"]
    offset = min(recv - stamp / args.speed for recv, stamp, _ in odoms)
    inside = [(recv, stamp) for recv, stamp, _ in odoms if recv >= window_start]
    rtf = slope(inside)
    per_5s: list[float] = []
    for begin in range(0, int(args.seconds) - 4, 5):
        chunk = [(r, s) for r, s in inside if window_start + begin <= r < window_start + begin + 5]
        if len(chunk) >= 3:
            per_5s.append(slope(chunk))
    late = [(recv - offset - stamp / args.speed) * 1000 for recv, stamp in inside]
    fifth = max(1, len(late) // 5)
    span = inside[-1][0] - inside[0][0]
    print(f"real-time factor (room time / wall, --speed {args.speed:g}): {rtf:.4f}, the slope of the /odom stamps "
          f"on their arrival over {span:.1f} s (N={len(inside)}); per 5 s {spread(per_5s, digits=4)}   "
          f"[bar >= 1.0 at speed 1]")
    print(f"an /odom's arrival after its room time: {spread(late, ' ms')}; median in the first fifth "
          f"{statistics.median(late[:fifth]):.2f} ms, the last {statistics.median(late[-fifth:]):.2f} ms "
          f"(the loop's lateness + delivery: a room falling behind would grow it)")
    for topic, hz in (("/scan", 10.0), ("/odom", 20.0), (CAMERA, 5.0)):
        times = [recv for recv, _, _ in received[topic] if recv >= window_start]
        gaps = [(b - a) * 1000 for a, b in zip(times, times[1:])]
        print(f"  {topic}: {len(times) / wall:.2f} Hz reached of {hz * args.speed:g} Hz; "
              f"gaps {spread(gaps, ' ms', 1)}; {sizes.get(topic, 0) / 1024:.1f} KiB per message as JSON")
    print(f"served process: {100 * share:.1f}% of one core over {wall:.1f} s, per second "
          f"{spread([100 * x for x in seconds], '%', 1)}")
    print(f"  peak RSS {memory['VmHWM']:.0f} MB, RSS at the end {memory['VmRSS']:.0f} MB  "
          f"[bar <= 300 MB]")

    # publish -> applied, from the session's record
    from safeembodai_plugins.state.review import open_run

    store = open_run(folder)
    steps = store.steps("MO/live/rosbridge/0")
    store.close()
    shutil.rmtree(out, ignore_errors=True)
    if len(steps) != len(published):
        print(f"  ! the record holds {len(steps)} commands of {len(published)} published")
    lags, checks, visible = [], [0, 0], []
    carrying: dict[float, list[tuple[float, float]]] = {}  # angular.z -> the /odom (arrival, stamp) showing it
    for recv, stamp, angular in odoms:
        carrying.setdefault(angular, []).append((recv, stamp))
    for k, (step, sent) in enumerate(zip(steps, published)):
        shown = re.search(r"angular\.z (-?\d+\.\d+)", step.instruction)
        if shown is None or abs(float(shown.group(1)) - command(k)[1]) > 5e-4:
            print(f"  ! step {step.step} is not command {k}: {step.instruction[:120]}")
            continue
        if sent < window_start:
            continue
        applied = offset + step.sim_time_s / args.speed
        lags.append((applied - sent) * 1000)
        first = next((seen for seen in carrying.get(command(k)[1], []) if seen[0] >= sent), None)
        if first is not None and first[0] - sent < 1.0:  # the value recurs 10 s later
            visible.append((first[0] - sent) * 1000)
            checks[0] += 1
            checks[1] += first[1] / args.speed + offset >= applied - 1e-4
    print(f"a /cmd_vel published -> the room holding it (its record's time): {spread(lags, ' ms')}  "
          f"[bar: median <= 20 ms]")
    print(f"  over-estimated by the quickest /odom's delivery; the wire's one way (half a ping's round trip "
          f"through the served process): {spread([rtt * 500 for rtt in received['ping'] if rtt], ' ms')}")
    print(f"  outside check: {checks[1]} of {checks[0]} commands seen on /odom were stamped at or after the "
          f"record's time; publish -> the first /odom carrying it arrived: {spread(visible, ' ms')} "
          f"(includes the wait for the next /odom, 0-50 ms)")
    profile.report()


# -- guard-node's decision, in process --------------------------------------------------------------

def room_scan(beams: int, time_s: float = 0.0, ahead: float = 0.0) -> dict:
    """A LaserScan as rosbridge's JSON carries it: a 6 x 4 m room seen by a scanner ``ahead`` m before
    a robot at (2.0, 2.0) heading +x, a 0.1 m post 0.75 m ahead of the robot and 0.2 m left, an open door
    behind (no return: null), every 33rd beam a dropout (null)."""
    from safeembodai_core.rosbridge.frames import encode_frame
    from safeembodai_core.serve_robot.messages import header

    ranges: list[float | None] = []
    increment = 2 * math.pi / beams
    for k in range(beams):
        a = -math.pi + k * increment
        c, s = math.cos(a), math.sin(a)
        hits = []
        if c > 1e-9:
            hits.append((4.0 - ahead) / c)
        if c < -1e-9:
            y_at_wall = 2.0 + (-(2.0 + ahead) / c) * s
            hits.append(-(2.0 + ahead) / c if not 1.4 <= y_at_wall <= 2.6 else math.inf)  # the door
        if s > 1e-9:
            hits.append(2.0 / s)
        if s < -1e-9:
            hits.append(-2.0 / s)
        b = (0.75 - ahead) * c + 0.2 * s
        d2 = b * b - ((0.75 - ahead) ** 2 + 0.2 ** 2 - 0.1 ** 2)
        if d2 >= 0 and b > 0:
            hits.append(b - math.sqrt(d2))
        hit = min(hits)
        ranges.append(None if k % 33 == 0 or hit > 8.0 else round(hit, 4))
    message = {"header": header(time_s, "base_scan"), "angle_min": -math.pi, "angle_max": math.pi - increment,
               "angle_increment": increment, "time_increment": 0.0, "scan_time": 0.025, "range_min": 0.05,
               "range_max": 8.0, "ranges": ranges, "intensities": []}
    return json.loads(encode_frame({"op": "publish", "topic": "/scan", "msg": message}))["msg"]


def odometry(time_s: float) -> dict:
    from safeembodai_core.models import Pose
    from safeembodai_core.rosbridge.frames import encode_frame
    from safeembodai_core.serve_robot.messages import odometry as odometry_message

    pose = Pose(x_mm=2000.0 + 30.0 * (time_s % 1.0), y_mm=2000.0, heading_deg=2.0 * math.sin(time_s))
    return json.loads(encode_frame({"op": "publish", "topic": "/odom", "msg": odometry_message(pose, 0.2, 0.0,
                                                                                                 time_s)}))["msg"]


MIX = [(0.3, 0.0), (0.45, 0.0), (0.4, 0.5), (0.0, 1.0), (-0.2, 0.3), (0.5, -0.4)]


def twist(linear: float, angular: float) -> dict:
    return {"linear": {"x": linear, "y": 0.0, "z": 0.0}, "angular": {"x": 0.0, "y": 0.0, "z": angular}}


def build_node(body: str, null_range: str):
    """A GuardNode as ``safeembodai guard-node`` builds it (its defaults), for ``body`` (``disc``: the
    CLI's default 170 mm disc; ``footprint``: ``docs/examples/robot.yaml``'s) and ``null_range``."""
    from safeembodai_core import Guard
    from safeembodai_core.guard_node.node import GuardNode

    robot = robot_file(body, null_range)
    guard = Guard(["command_limits", {"use": "swept_body", "options": {"margin_mm": 50.0}}], robot=robot.robot_spec())
    return GuardNode(guard, robot, mode="limit", horizon_s=1.0, scan_timeout_s=0.5, period_s=0.05)


def robot_file(body: str, null_range: str):
    from safeembodai_core.ros.robot_file import RobotFile, ScanSource, parse_robot_file

    if body == "disc":
        return RobotFile(radius_mm=170.0, scans={"/scan": ScanSource(null_range=null_range)})
    return parse_robot_file(footprint_yaml(null_range), "docs/examples/robot.yaml")


def footprint_yaml(null_range: str) -> str:
    """``docs/examples/robot.yaml`` with ``null_range`` set."""
    text = (ROOT / "docs/examples/robot.yaml").read_text()
    return re.sub(r"null_range: \w+", f"null_range: {null_range}", text)


def decide(args: argparse.Namespace) -> None:
    from safeembodai_core.rosbridge.frames import encode_frame, read_frame

    os.sched_setaffinity(0, {args.core})  # in process: the node's thread on the one core
    print(f"== guard-node's decision in process on core {args.core} ({conditions()})")
    print(f"{'robot':28} {'beams':>5} {'on_scan ms':>24} {'on_odom ms':>10} {'on_command ms':>24} "
          f"{'scan + command ms':>24} {'frame read':>10}  actions")
    robots = {"disc 170, no_return": ("disc", "no_return"), "footprint, no_return": ("footprint", "no_return"),
              "disc 170, unknown (default)": ("disc", "unknown")}
    for name, (body, null_range) in robots.items():
        for beams in (360, 720):
            node = build_node(body, null_range)
            scan = room_scan(beams, ahead=0.12 if body == "footprint" else 0.0)  # the example's scanner mount
            frame = encode_frame({"op": "publish", "topic": "/scan", "msg": scan})
            samples: dict[str, list[float]] = {"scan": [], "odom": [], "command": [], "read": []}
            actions: dict[str, int] = {}
            for k in range(args.repeat + 20):
                t = k * 0.05
                scan["header"]["stamp"]["sec"] = int(t)
                messages = [("odom", node.on_odom, odometry(t), t), ("scan", node.on_scan, scan, t + 0.01),
                            ("command", node.on_command, twist(*MIX[(k // 20) % len(MIX)]), t + 0.02)]
                for part, call, message, at in messages:
                    begun = time.perf_counter()
                    answer = call(message, at)
                    if k >= 20:
                        samples[part].append((time.perf_counter() - begun) * 1000)
                if k >= 20:
                    actions[answer.action] = actions.get(answer.action, 0) + 1
                if k % 5 == 0:
                    begun = time.perf_counter()
                    read_frame(frame)
                    samples["read"].append((time.perf_counter() - begun) * 1000)
            both = [a + b for a, b in zip(samples["scan"], samples["command"])]
            print(f"{name:28} {beams:5d} {short(samples['scan']):>24} {statistics.median(samples['odom']):10.3f} "
                  f"{short(samples['command']):>24} {short(both):>24} {statistics.median(samples['read']):10.3f}  "
                  f"{actions}")
    print(f"N={args.repeat} decisions per row (after 20 warm-up), each on a fresh scan; medians (p90) in ms. "
          f"[bar: a decision <= 5 ms median]")


# -- guard-node on the wire -------------------------------------------------------------------------

def guard(args: argparse.Namespace) -> None:
    from safeembodai_core.rosbridge.server import RosbridgeServer

    keep_off(args.core)
    print(f"== guard-node on the wire, on core {args.core} ({conditions()})")
    server = RosbridgeServer("127.0.0.1", 0, node="/bench_robot")
    server.offer_topic("/scan", LASER_SCAN)
    server.offer_topic("/odom", ODOMETRY)
    server.start()
    stop = threading.Event()
    folder = Path(tempfile.mkdtemp(prefix="live_wire_"))
    robots = {"disc": "radius_mm: 170\nscans:\n  /scan: {null_range: no_return}\n",
              "footprint": footprint_yaml("no_return")}
    try:
        sensors = threading.Thread(target=publish_sensors, args=(server, room_scan(360), stop), daemon=True)
        sensors.start()
        guard_run(args, [sys.executable, "-c", WIRE_ALONE, f"ws://127.0.0.1:{server.port}"], r"^relaying",
                  "the wire alone (a RosbridgeClient relaying /cmd_vel_in to /cmd_vel, no guard)", server.port)
        stop.set()
        sensors.join()
        stop.clear()
        for body, text in robots.items():
            scan = room_scan(360, ahead=0.12 if body == "footprint" else 0.0)
            sensors = threading.Thread(target=publish_sensors, args=(server, scan, stop), daemon=True)
            sensors.start()
            (folder / f"{body}.yaml").write_text(text)
            name = "disc 170 mm" if body == "disc" else "the example's footprint (scanner 120 mm ahead)"
            guard_run(args, ["guard-node", "--rosbridge", f"ws://127.0.0.1:{server.port}", "--robot",
                             str(folder / f"{body}.yaml")], r"^guarding ", f"guard-node, {name}, null_range no_return",
                      server.port)
            stop.set()
            sensors.join()
            stop.clear()
    finally:
        stop.set()
        server.stop()
        shutil.rmtree(folder, ignore_errors=True)


#: The floor of guard-node's traffic: its subscriptions, a publish per command and per 20 Hz cycle, no guard.
WIRE_ALONE = """
import sys, time
from safeembodai_core.rosbridge.client import RosbridgeClient
held = []
client = RosbridgeClient(sys.argv[1]).connect()
client.advertise("/cmd_vel", "geometry_msgs/msg/Twist")
client.subscribe("/scan", "sensor_msgs/msg/LaserScan", lambda m: None, queue_length=1)
client.subscribe("/odom", "nav_msgs/msg/Odometry", lambda m: None, queue_length=1)
client.subscribe("/cmd_vel_in", "geometry_msgs/msg/Twist",
                 lambda m: (held.append(m), client.publish("/cmd_vel", m)), queue_length=1)
print("relaying", flush=True)
next_at = time.monotonic()


def wait(seconds):
    time.sleep(seconds)


try:
    while True:
        if held:
            client.publish("/cmd_vel", held[-1])
        next_at += 0.05
        wait(max(0.0, next_at - time.monotonic()))
except KeyboardInterrupt:
    client.close()
    print("relayed")
"""


def publish_sensors(server, scan: dict, stop: threading.Event) -> None:
    """``/scan`` at 40 Hz, ``/odom`` at 20 Hz, until ``stop``."""
    begun, k = time.monotonic(), 0
    while not stop.is_set():
        t = time.monotonic() - begun
        scan["header"]["stamp"] = {"sec": int(t), "nanosec": int((t % 1) * 1e9)}
        server.publish("/scan", scan)
        if k % 2 == 0:
            server.publish("/odom", odometry(t))
        k += 1
        stop.wait(max(0.0, begun + k * 0.025 - time.monotonic()))


def guard_run(args: argparse.Namespace, command: list[str], ready: str, name: str, port: int) -> None:
    from safeembodai_core.rosbridge.client import RosbridgeClient

    cli = Cli(args.core, command, ready)
    counts = {"/cmd_vel": 0, "/safeembodai/guard": 0}
    actions: dict[str, int] = {}
    counting = threading.Event()

    def count(topic: str, message: dict) -> None:
        if counting.is_set():
            counts[topic] += 1
            if topic == "/safeembodai/guard":
                action = json.loads(message["data"])["action"]
                actions[action] = actions.get(action, 0) + 1

    planner = RosbridgeClient(f"ws://127.0.0.1:{port}").connect()
    planner.advertise("/cmd_vel_in", TWIST)
    planner.subscribe("/cmd_vel", TWIST, lambda m: count("/cmd_vel", m))
    planner.subscribe("/safeembodai/guard", STRING, lambda m: count("/safeembodai/guard", m))
    begun = time.monotonic()
    window = profile = None
    for k in range(int((args.warmup + args.seconds) * 20)):
        time.sleep(max(0.0, begun + k * 0.05 - time.monotonic()))
        if k == int(args.warmup * 20):
            window, profile = Window(cli.pid), Profile(args.py_spy, cli.pid, args.seconds)
            counting.set()
        elif window is not None and k % 20 == 0:
            window.tick()
        planner.publish("/cmd_vel_in", twist(*MIX[(k // 20) % len(MIX)]))
    assert window is not None and profile is not None
    wall, share, seconds = window.close()
    counting.clear()
    memory = memory_mb(cli.pid)
    planner.close()
    cli.end()
    print(f"{name}: {100 * share:.1f}% of one core over {wall:.1f} s; "
          f"per second {spread([100 * x for x in seconds], '%', 1)}{'  [bar <= 10%]' * name.startswith('guard')}")
    print(f"  at 40 Hz scans (360 beams), 20 Hz odometry, 20 Hz commands; peak RSS {memory['VmHWM']:.0f} MB, "
          f"RSS at the end {memory['VmRSS']:.0f} MB  [bar <= 300 MB]")
    print(f"  it sent {counts['/cmd_vel'] / wall:.1f} /cmd_vel a second and {counts['/safeembodai/guard'] / wall:.1f} "
          f"decisions a second ({actions}); it said: {cli.lines[-1][:160] if cli.lines else ''}")
    profile.report()


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("part", choices=["serve", "decide", "guard", "all"])
    parser.add_argument("--seconds", type=float, default=None, help="measured window (serve 30, guard 20)")
    parser.add_argument("--warmup", type=float, default=None, help="seconds before the window (serve 5, guard 3)")
    parser.add_argument("--repeat", type=int, default=1000, help="decisions per row (decide)")
    parser.add_argument("--speed", type=float, default=1.0, help="serve-robot's --speed (serve)")
    parser.add_argument("--core", type=int, default=0, help="the core the measured process runs on")
    parser.add_argument("--profile", action="store_true", help="py-spy the measured process over the window")
    parser.add_argument("--py-spy", dest="py_spy", default=shutil.which("py-spy"), help="py-spy's path")
    args = parser.parse_args()
    parts = ["serve", "decide", "guard"] if args.part == "all" else [args.part]
    if not args.profile:
        args.py_spy = None
    elif not args.py_spy:
        parser.error("--profile needs py-spy (pip install py-spy, or --py-spy PATH)")
    for part in parts:
        own = argparse.Namespace(**vars(args))
        own.seconds = args.seconds or {"serve": 30.0, "guard": 20.0}.get(part, 0.0)
        own.warmup = args.warmup if args.warmup is not None else {"serve": 5.0, "guard": 3.0}.get(part, 0.0)
        {"serve": serve, "decide": decide, "guard": guard}[part](own)


if __name__ == "__main__":
    main()
