"""``safeembodai serve-robot SCENARIO``: one room served as a rosbridge v2 robot, on the wall clock."""

from __future__ import annotations

import signal
import threading

import click

from .common import load, scenario_options


@click.command("serve-robot")
@scenario_options
@click.option("--environment", "label", default=None, help="Environment label (default: the scenario's first).")
@click.option("--host", default="127.0.0.1", show_default=True,
              help="Address to listen on. rosbridge has no authentication: whoever reaches it drives the robot.")
@click.option("--port", type=click.IntRange(0, 65535), default=9090, show_default=True,
              help="Port (0: any free one, printed).")
@click.option("--out", "out", type=click.Path(file_okay=False), default="runs", show_default=True,
              help="Folder the session's run folder goes in.")
@click.option("--speed", type=click.FloatRange(0.01, 100.0), default=1.0, show_default=True,
              help="The room's time per wall-clock second.")
@click.option("--scan-hz", type=click.FloatRange(0.1, 100.0), default=10.0, show_default=True)
@click.option("--odom-hz", type=click.FloatRange(0.1, 200.0), default=20.0, show_default=True)
@click.option("--camera-hz", type=click.FloatRange(0.1, 60.0), default=5.0, show_default=True)
@click.option("--cmd-vel-timeout", "cmd_vel_timeout", type=click.FloatRange(0.01, 60.0), default=0.5,
              show_default=True, help="Seconds a velocity command is held without a new one (diff_drive_controller's).")
@click.option("--allow-origin", "allowed_origins", multiple=True, metavar="URL",
              help="A browser origin that may connect (a dashboard: https://host:port); pages of any other origin "
                   "are refused. Repeatable.")
@click.option("--bag", type=click.Choice(["mcap", "sqlite3", "none"]), default="mcap", show_default=True,
              help="The session's ROS 2 bag in the run folder's bags/ (what the room served and was told; "
                   "docs/robots.md); none: no bag.")
def serve_robot(scenario_path, backend, seed, overrides, label, host, port, out, speed, scan_hz, odom_hz, camera_hz,
                cmd_vel_timeout, allowed_origins, bag) -> None:
    """Serve one room of SCENARIO as a rosbridge v2 robot: /scan, /odom, the camera and events out,
    /cmd_vel in; the session is recorded as a run folder (show, report, view) with its ROS 2 bag (export).
    Ctrl-C ends it."""
    from rich.console import Console

    from ..serve_robot.served_room import Rates
    from ..serve_robot.session import Session, prepare_session
    from ..trust.text import terminal_markup

    scenario, plugins = load(scenario_path, backend, seed, overrides)
    session = prepare_session(scenario, plugins, label=label, host=host, port=port, out=out, speed=speed,
                              rates=Rates(scan_hz, odom_hz, camera_hz, cmd_vel_timeout),
                              bag=None if bag == "none" else bag, allowed_origins=allowed_origins)
    console = Console(emoji=False)

    def ready(session: Session) -> None:
        console.print(f"serving {terminal_markup(session.label)} (seed {session.seed}) at "
                      f"ws://{terminal_markup(session.host)}:{session.port}; recording to "
                      f"{terminal_markup(str(session.folder))}; Ctrl-C ends it")

    if threading.current_thread() is threading.main_thread():
        signal.signal(signal.SIGTERM, lambda number, frame: session.stop("SIGTERM"))
        signal.signal(signal.SIGINT, lambda number, frame: session.stop("SIGINT"))
    record = session.serve(on_ready=ready)
    result = record.result
    if result is not None:
        console.print(f"{terminal_markup(result.spec.trial_id)}: {result.outcome.value} after {result.steps} "
                      f"commands; {terminal_markup(result.detail)}")
    if record.bag is not None:
        console.print(f"bag: {terminal_markup(str(record.bag.path))}" if record.bag.path is not None
                      else f"no bag: it could not be written ({terminal_markup(record.bag.error)})")
    console.print(f"recorded in {terminal_markup(str(record.path))}")
