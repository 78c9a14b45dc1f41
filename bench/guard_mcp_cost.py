"""What guard-mcp adds to an agent's call, against ros-mcp direct (issue 49, part 7).

    python bench/guard_mcp_cost.py [--calls 200] [--repeat 1000] [--profile]

A :class:`~safeembodai_core.rosbridge.server.RosbridgeServer` in this process is the robot: ``/scan``
(360 beams of a 6 x 4 m room, ``null`` for no return) at 10 Hz, ``/odom`` at 20 Hz, ``/cmd_vel``
accepted and counted. Two official MCP clients (``mcp``, over stdio) talk to it at once:

* **direct**: ros-mcp (``SAFEEMBODAI_ROS_MCP``, or ``ros-mcp`` on the path) pointed at the robot;
* **guarded**: ``safeembodai guard-mcp --upstream-cmd ros-mcp`` (its own ros-mcp), the shipped policy,
  a 170 mm disc reading ``null`` as no return, its session recorded under a scratch folder;
* **bare proxy**: the floor of being an MCP proxy at all: the same low-level ``Server`` and upstream
  session (guard-mcp's ``open_upstream``) forwarding every call as it came, nothing read, judged,
  marked or recorded (its own ros-mcp).

Each makes ``--calls`` calls of two kinds, the paths taking turns call by call (so a change of load
falls on both): ``get_topics`` (read-only: forwarded, its answer marked untrusted, recorded) and
``publish_for_durations`` of one 0.2 m/s message for 0.05 s at ``rate_hz`` 10 (judged with the
base's 1 s hold after it on the newest scan, forwarded as one slice, recorded; ros-mcp streams it
for 0.05 s, then sleeps to its next period: about 0.1 s a call. At ``rate_hz`` 0 ros-mcp waits a
second for an error after each message, on both paths alike), after 20 of each to warm up. Per
kind: the wall time of a call on each path (median, p90) and the difference of the medians; the CPU
that guard-mcp's own process spent per call (``/proc/PID/stat``, all its threads: both MCP sessions,
the judgement, the marking, the record's writer, and its rosbridge client reading the scans), gross
and net of what it spends idle (measured over ``--idle`` seconds before), split by thread
(``/proc/PID/task``), apart from the CPU of its ros-mcp and of the direct ros-mcp per call. Then
guard-mcp's peak RSS (VmHWM). ``--profile`` also runs guard-mcp under cProfile (its event loop's
thread) and prints its costliest functions; the timings of that run are not the figures.

In process (``--repeat`` calls each, medians): the verdict alone (``read_call``, the plan, and
``MotionJudge.judge`` on the same scan read from rosbridge's JSON, as ``bench/guard_twist.py`` times
``check_twist``), and :meth:`GuardMcp.call` whole with an upstream that answers at once (the same two
kinds, the publish for 0 s so that it is one slice: our Python work without the transports).
``--profile``: cProfile of those in-process calls too.

Numbers, never asserts. Bars (issue 49): our own work per call at most 5 ms (median), the verdict at
most 2 ms, guard-mcp's memory at most 300 MB.
"""

from __future__ import annotations

import argparse
import asyncio
import contextlib
import cProfile
import json
import os
import pstats
import shutil
import statistics
import sys
import tempfile
import threading
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from live_wire import conditions, cpu_seconds, memory_mb, odometry, quantile, room_scan, twist  # noqa: E402

ROOT = Path(__file__).resolve().parent.parent
TWIST = "geometry_msgs/msg/Twist"
KINDS = {"get_topics": {},
         "publish_for_durations": {"topic": "/cmd_vel", "msg_type": TWIST, "messages": [twist(0.2, 0.0)],
                                   "durations": [0.05], "rate_hz": 10}}


def ros_mcp() -> str:
    found = os.environ.get("SAFEEMBODAI_ROS_MCP") or shutil.which("ros-mcp")
    if not found:
        sys.exit("ros-mcp is needed: python -m venv ros-mcp-venv && ros-mcp-venv/bin/pip install ros-mcp==3.1.2, "
                 "then SAFEEMBODAI_ROS_MCP=ros-mcp-venv/bin/ros-mcp")
    return found


def thread_cpu(pid: int) -> dict[str, float]:
    """utime + stime of each of ``pid``'s threads, summed by thread name (``/proc/PID/task``)."""
    found: dict[str, float] = {}
    for task in Path(f"/proc/{pid}/task").iterdir():
        try:
            name = (task / "comm").read_text().strip()
            fields = (task / "stat").read_text().rsplit(")", 1)[1].split()
        except OSError:
            continue
        name = "event loop (main)" if task.name == str(pid) else name.rstrip("0123456789_-")
        found[name] = found.get(name, 0.0) + (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")
    return found


def children(pid: int) -> dict[int, str]:
    """The processes whose parent is ``pid``, with their command lines."""
    found = {}
    for entry in Path("/proc").iterdir():
        if not entry.name.isdigit():
            continue
        try:
            parent = int((entry / "stat").read_text().rsplit(")", 1)[1].split()[1])
            if parent == pid:
                found[int(entry.name)] = (entry / "cmdline").read_bytes().replace(b"\0", b" ").decode()
        except (OSError, ValueError, IndexError):
            continue
    return found


class Robot:
    """The robot: a rosbridge server serving ``/scan`` at 10 Hz and ``/odom`` at 20 Hz, counting ``/cmd_vel``."""

    def __init__(self) -> None:
        from safeembodai_core.rosbridge.server import RosbridgeServer

        self.server = RosbridgeServer("127.0.0.1", 0, node="/bench_robot")
        self.server.offer_topic("/scan", "sensor_msgs/msg/LaserScan")
        self.server.offer_topic("/odom", "nav_msgs/msg/Odometry")
        self.commands = 0
        self.server.accept_topic("/cmd_vel", [TWIST], self._command)
        self.server.start()
        self.port = self.server.port
        self.scan = room_scan(360)
        self.stop = threading.Event()
        threading.Thread(target=self._publish, daemon=True).start()

    def _command(self, type_: str, message: dict, client: str) -> None:
        self.commands += 1

    def _publish(self) -> None:
        begun, k = time.monotonic(), 0
        while not self.stop.is_set():
            t = time.monotonic() - begun
            if k % 2 == 0:
                self.scan["header"]["stamp"] = {"sec": int(t), "nanosec": int((t % 1) * 1e9)}
                self.server.publish("/scan", self.scan)
            self.server.publish("/odom", odometry(t))
            k += 1
            self.stop.wait(max(0.0, begun + k * 0.05 - time.monotonic()))

    def close(self) -> None:
        self.stop.set()
        self.server.stop()


@contextlib.asynccontextmanager
async def client(command: list[str], log):
    from mcp import ClientSession
    from mcp.client.stdio import StdioServerParameters, get_default_environment, stdio_client

    env = {**get_default_environment(), "FASTMCP_CHECK_FOR_UPDATES": "off", "FASTMCP_SHOW_CLI_BANNER": "false",
           "PYTHONPATH": str(ROOT)}
    async with stdio_client(StdioServerParameters(command=command[0], args=command[1:], env=env),
                            errlog=log) as (read, write):
        async with ClientSession(read, write) as session:
            await session.initialize()
            yield session


async def timed(session, tool: str) -> float:
    started = time.perf_counter()
    result = await session.call_tool(tool, KINDS[tool])
    took = time.perf_counter() - started
    if result.isError:
        raise RuntimeError(f"{tool} failed: {result.content}")
    return took


BARE_PROXY = """
import sys
import anyio
from mcp.server.lowlevel import Server
from mcp.server.stdio import stdio_server
from safeembodai_core.guard_mcp.upstream import open_upstream


async def main():
    async with open_upstream(sys.argv[1]) as upstream:
        await upstream.call("connect_to_robot", {"ip": "127.0.0.1", "port": int(sys.argv[2])})
        server = Server("bare-proxy")

        @server.list_tools()
        async def list_tools():
            return upstream.tools

        @server.call_tool(validate_input=False)
        async def call_tool(name, arguments):
            return await upstream.call(name, arguments)

        async with stdio_server() as (read, write):
            await server.run(read, write, server.create_initialization_options())

anyio.run(main)
"""


def ms(values: list[float]) -> str:
    return f"{1000 * statistics.median(values):.2f} (p90 {1000 * quantile(values, 0.9):.2f})"


async def on_the_wire(args: argparse.Namespace, robot: Robot, folder: Path) -> dict:
    script = ros_mcp()
    (folder / "robot.yaml").write_text("radius_mm: 170\nscans:\n  /scan: {null_range: no_return}\n")
    profiled = ["-m", "cProfile", "-o", str(folder / "guard-mcp.prof")] if args.profile else []
    guarded_cmd = [sys.executable, *profiled, "-m", "safeembodai_core", "guard-mcp", "--upstream-cmd", script,
                   "--rosbridge", f"ws://127.0.0.1:{robot.port}", "--robot", str(folder / "robot.yaml"), "--out",
                   str(folder / "runs")]
    (folder / "bare_proxy.py").write_text(BARE_PROXY)
    bare_cmd = [sys.executable, str(folder / "bare_proxy.py"), script, str(robot.port)]
    with open(folder / "servers.log", "w") as log:
        async with client([script], log) as direct, client(guarded_cmd, log) as guarded, \
                client(bare_cmd, log) as bare:
            await direct.call_tool("connect_to_robot", {"ip": "127.0.0.1", "port": robot.port})
            procs = children(os.getpid())
            guard_pid = next(pid for pid, line in procs.items() if "guard-mcp" in line)
            bare_pid = next(pid for pid, line in procs.items() if "bare_proxy" in line)
            direct_pid = next(pid for pid, line in procs.items() if pid not in (guard_pid, bare_pid))
            pids = {"guard-mcp": guard_pid, "its ros-mcp": next(iter(children(guard_pid))), "bare proxy": bare_pid,
                    "direct ros-mcp": direct_pid}
            paths = {"direct": direct, "guarded": guarded, "bare proxy": bare}
            for tool in KINDS:
                for _ in range(20):
                    for session in paths.values():
                        await timed(session, tool)
            idle_cpu, idle_begun = {name: cpu_seconds(pid) for name, pid in pids.items()}, time.monotonic()
            await asyncio.sleep(args.idle)
            idle_wall = time.monotonic() - idle_begun
            idle = {name: (cpu_seconds(pid) - idle_cpu[name]) / idle_wall for name, pid in pids.items()}
            figures = {"idle": idle, "pids": pids}
            for tool in KINDS:
                times: dict[str, list[float]] = {path: [] for path in paths}
                cpu0, wall0 = {name: cpu_seconds(pid) for name, pid in pids.items()}, time.monotonic()
                threads0 = thread_cpu(guard_pid)
                for _ in range(args.calls):
                    for path, session in paths.items():
                        times[path].append(await timed(session, tool))
                wall = time.monotonic() - wall0
                cpu = {name: (cpu_seconds(pid) - cpu0[name]) / args.calls for name, pid in pids.items()}
                threads = {name: (seconds - threads0.get(name, 0.0)) / args.calls
                           for name, seconds in thread_cpu(guard_pid).items()}
                figures[tool] = {"times": times, "cpu": cpu, "wall": wall, "threads": threads}
            figures["rss"] = {name: memory_mb(pid) for name, pid in pids.items()}
            figures["commands"] = robot.commands
    return figures


def report_wire(args: argparse.Namespace, figures: dict) -> None:
    idle = figures["idle"]
    print(f"idle over {args.idle:g} s (CPU share of a core): "
          + ", ".join(f"{name} {100 * share:.2f}%" for name, share in idle.items()))
    for tool in KINDS:
        f = figures[tool]
        direct, guarded, bare = f["times"]["direct"], f["times"]["guarded"], f["times"]["bare proxy"]
        added = statistics.median(guarded) - statistics.median(direct)
        own = f["cpu"]["guard-mcp"]
        net = own - idle["guard-mcp"] * f["wall"] / args.calls
        floor = f["cpu"]["bare proxy"] - idle["bare proxy"] * f["wall"] / args.calls
        print(f"{tool} (N={args.calls} each, taking turns): direct {ms(direct)} ms, guarded {ms(guarded)} ms, bare "
              f"proxy {ms(bare)} ms; added by guard-mcp {1000 * added:.2f} ms (median of guarded - median of direct), "
              f"by the bare proxy {1000 * (statistics.median(bare) - statistics.median(direct)):.2f} ms")
        print(f"  CPU per call: guard-mcp {1000 * own:.2f} ms (net of idle {1000 * net:.2f} ms); the bare proxy net "
              f"{1000 * floor:.2f} ms; guard-mcp's ros-mcp {1000 * f['cpu']['its ros-mcp']:.2f} ms; direct ros-mcp "
              f"{1000 * f['cpu']['direct ros-mcp']:.2f} ms")
        print("  guard-mcp's threads, CPU per call (gross): " + ", ".join(
            f"{name} {1000 * seconds:.2f} ms" for name, seconds in sorted(f["threads"].items(), key=lambda i: -i[1])
            if seconds > 0))
    rss = figures["rss"]
    print("peak RSS: " + ", ".join(f"{name} {values['VmHWM']:.0f} MB" for name, values in rss.items()))
    print(f"/cmd_vel messages the robot received: {figures['commands']}")


def rig():
    """A GuardMcp as the CLI builds it (shipped policy, 170 mm disc, null as no return) with senses fed the
    bench's scan and an upstream that answers at once."""
    from mcp import types

    from safeembodai_core import Guard
    from safeembodai_core.guard_mcp.judging import MotionJudge
    from safeembodai_core.guard_mcp.policy import read_policy
    from safeembodai_core.guard_mcp.proxy import GuardMcp
    from safeembodai_core.guard_mcp.senses import RobotSenses
    from safeembodai_core.ros.robot_file import RobotFile

    policy = read_policy()
    robot = RobotFile(radius_mm=170.0, scans={"/scan": {"null_range": "no_return"}})
    guard = Guard(["command_limits", {"use": "swept_body", "options": {"margin_mm": policy.margin_mm}}],
                  robot=robot.robot_spec())
    senses = RobotSenses(robot, scan_timeout_s=1e9, odom_topic=None)
    senses.on_scan(room_scan(360))
    topics = {"topics": ["/scan", "/odom", "/cmd_vel"], "types": ["sensor_msgs/msg/LaserScan", "nav_msgs/msg/Odometry",
                                                                  TWIST]}

    async def upstream(tool, arguments):
        content = topics if tool == "get_topics" else {"success": True, "published_count": 1}
        return types.CallToolResult(content=[types.TextContent(type="text", text=json.dumps(content))],
                                    structuredContent=content)

    judge = MotionJudge(guard, robot, policy)
    return GuardMcp(policy, judge, senses, upstream, ("127.0.0.1", 9090)), judge, senses


def in_process(args: argparse.Namespace) -> None:
    from safeembodai_core.guard_mcp.calls import read_call

    mcp, judge, senses = rig()
    records = []
    mcp.on_call = records.append  # as the session's record is told (its writing is on a thread of its own)
    arguments = KINDS["publish_for_durations"]

    def verdict():
        motion = read_call("publish_for_durations", arguments, mcp.policy, mcp.robot)
        judged = judge.judge(judge.plan(motion), senses.view())
        assert judged.ok, judged.reasons

    def median_ms(call, repeat):
        for _ in range(20):
            call()
        times = []
        for _ in range(repeat):
            started = time.perf_counter()
            call()
            times.append(time.perf_counter() - started)
        return f"{1000 * statistics.median(times):.3f} ms (p90 {1000 * quantile(times, 0.9):.3f}, N={repeat})"

    loop = asyncio.new_event_loop()
    calls = {"the verdict alone (read_call + plan + judge)": verdict}
    once = {**arguments, "durations": [0.0], "rate_hz": 0}  # one slice: an instant upstream takes no time
    for tool, given in (("get_topics", KINDS["get_topics"]), ("publish_for_durations", once)):
        calls[f"GuardMcp.call {tool}, the upstream instant"] = (
            lambda tool=tool, given=given: loop.run_until_complete(mcp.call(tool, given)))
    for name, call in calls.items():
        print(f"{name}: {median_ms(call, args.repeat)}")
    if args.profile:
        for name, call in calls.items():
            profile = cProfile.Profile()
            profile.runcall(lambda: [call() for _ in range(args.repeat)])
            print(f"\ncProfile of {args.repeat} x {name} (cumulative, the costliest of ours):")
            stats = pstats.Stats(profile)
            stats.sort_stats("cumulative").print_stats(r"safeembodai_core|mcp/types|pydantic", 14)
    loop.close()


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--calls", type=int, default=200)
    parser.add_argument("--repeat", type=int, default=1000)
    parser.add_argument("--idle", type=float, default=10.0)
    parser.add_argument("--profile", action="store_true")
    parser.add_argument("--only", choices=["wire", "process"])
    args = parser.parse_args()
    print(conditions())
    if args.only != "wire":
        in_process(args)
    if args.only == "process":
        return
    robot = Robot()
    folder = Path(tempfile.mkdtemp(prefix="guard_mcp_cost_"))
    try:
        figures = asyncio.run(on_the_wire(args, robot, folder))
    finally:
        robot.close()
    report_wire(args, figures)
    if args.profile and (folder / "guard-mcp.prof").exists():
        print("\ncProfile of guard-mcp's event loop over the whole session (cumulative, ours and the SDK's):")
        stats = pstats.Stats(str(folder / "guard-mcp.prof"))
        stats.sort_stats("cumulative").print_stats(r"safeembodai_core/guard_mcp|mcp/(client|server|shared)/|"
                                                    r"jsonschema/validators.py.*(validate|check_schema)", 30)
    print(f"conditions at the end: {conditions()}")
    shutil.rmtree(folder, ignore_errors=True)


if __name__ == "__main__":
    main()
