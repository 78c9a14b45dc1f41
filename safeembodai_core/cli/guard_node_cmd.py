"""``safeembodai guard-node --rosbridge ws://HOST:PORT``: the guard live between a planner and the base."""

from __future__ import annotations

import signal
import threading

import click


@click.command("guard-node")
@click.option("--rosbridge", "url", required=True, metavar="ws://HOST:PORT", help="The robot's rosbridge server.")
@click.option("--in", "command_in", default="/cmd_vel_in", show_default=True, help="The planner's command topic.")
@click.option("--out", "command_out", default="/cmd_vel", show_default=True, help="The base's command topic.")
@click.option("--scan", default=None, help="The scan topic (default: the robot file's first scan source).")
@click.option("--odom", default="/odom", show_default=True, help="The odometry topic ('' for none).")
@click.option("--robot", "robot_path", type=click.Path(dir_okay=False), default=None,
              help="The robot file (YAML: body, scanners, limits; docs/robot_file.md). Default: a disc of 170 mm, "
                   "one scanner at the centre on /scan whose null ranges are unknown.")
@click.option("--mode", type=click.Choice(["limit", "refuse"]), default="limit", show_default=True,
              help="limit: slow a command to what stays clear for the horizon; refuse: forward it or stop.")
@click.option("--horizon", "horizon_s", type=click.FloatRange(0.05, 30.0), default=1.0, show_default=True,
              help="Seconds a command is judged held for.")
@click.option("--scan-timeout", "scan_timeout_s", type=click.FloatRange(0.01, 30.0), default=0.5,
              show_default=True, help="A scan older than this stops the robot (Nav2's source_timeout).")
@click.option("--margin-mm", "margin_mm", type=click.FloatRange(0.0, 2000.0), default=50.0, show_default=True,
              help="Distance kept between the body and any return (swept_body's margin_mm).")
@click.option("--rate", "rate_hz", type=click.FloatRange(1.0, 200.0), default=20.0, show_default=True,
              help="Cycles a second (the smoother's frequency; held commands re-judged, stale scans caught).")
def guard_node(url, command_in, command_out, scan, odom, robot_path, mode, horizon_s, scan_timeout_s, margin_mm,
               rate_hz) -> None:
    """Guard a rosbridge robot: each command on --in is forwarded, slowed or stopped onto --out, judged
    on the robot's own latest scan; each decision goes to /safeembodai/guard."""
    from rich.console import Console

    from .. import Guard
    from ..guard_node.node import GuardNode
    from ..guard_node.wire import GuardWire
    from ..ros.robot_file import RobotFile, ScanSource, read_robot_file
    from ..trust.text import terminal_markup

    robot = read_robot_file(robot_path) if robot_path else RobotFile(radius_mm=170.0,
                                                                     scans={scan or "/scan": ScanSource()})
    guard = Guard(["command_limits", {"use": "swept_body", "options": {"margin_mm": margin_mm}}],
                  robot=robot.robot_spec())
    node = GuardNode(guard, robot, scan_topic=scan, mode=mode, horizon_s=horizon_s, scan_timeout_s=scan_timeout_s,
                     period_s=1.0 / rate_hz)
    wire = GuardWire(node, url, command_in=command_in, command_out=command_out, scan=scan, odom=odom or None,
                     period_s=1.0 / rate_hz)
    if threading.current_thread() is threading.main_thread():
        signal.signal(signal.SIGTERM, lambda number, frame: wire.stop("SIGTERM"))
        signal.signal(signal.SIGINT, lambda number, frame: wire.stop("SIGINT"))
    console = Console(emoji=False)
    wire.start()
    console.print(f"guarding {terminal_markup(command_in)} -> {terminal_markup(command_out)} on "
                  f"{terminal_markup(url)} ({mode}, horizon {horizon_s:g} s); Ctrl-C ends it")
    try:
        wire.run()
    finally:
        wire.close()
    console.print(f"sent {wire.sent} commands, {wire.decisions} decisions published; unread messages: "
                  f"{terminal_markup(str(node.unread))}")
