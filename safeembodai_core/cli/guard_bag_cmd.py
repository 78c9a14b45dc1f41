"""``safeembodai guard-bag BAG``: which recorded commands would the guard have refused, when and why.

Reads a ROS 2 bag (MCAP or SQLite) with ``rosbags`` -- no ROS install -- and judges every command on
``--cmd`` with the latest ``--scan`` before it (:func:`~safeembodai_core.guard.bag_guard.guard_bag`).
Rules: ``--rules`` (names, or JSON ``{"use": ..., "options": {...}}``), else -- with
``--rules-from-bag`` -- the rules a bag written by ``safeembodai`` recorded for its trial
(``/safeembodai/trial``), else the Guard's robot defaults (``command_limits``, ``swept_body``).
``--limit`` adds, per Twist, the speed the guard would have allowed (``Guard.limit_twist``). The
report (a table, or ``--json``) is printed only once the whole bag has been judged.
"""

from __future__ import annotations

import json
import math
from typing import Any

import click


def _rule(text: str) -> Any:
    text = text.strip()
    if text.startswith("{"):
        try:
            value = json.loads(text)
        except json.JSONDecodeError as error:
            raise click.BadParameter(f"{text[:60]!r} is not JSON: {error}", param_hint="--rules") from None
        if not isinstance(value, dict):
            raise click.BadParameter("a rule in JSON must be an object", param_hint="--rules")
        return value
    return text


def recorded_trial(bag: str) -> dict[str, Any]:
    """What a bag written by ``safeembodai`` says of its trial (robot, limits, the arm's rules); {} otherwise."""
    from ..guard.bag_guard import open_bag

    reader = open_bag(bag)
    try:
        found = [c for c in reader.connections
                 if c.topic == "/safeembodai/trial" and c.msgtype == "std_msgs/msg/String"]
        if not found:  # (rosbags reads every topic when given none)
            return {}
        try:
            for connection, _, raw in reader.messages(connections=found):
                value = json.loads(reader.deserialize(raw, connection.msgtype).data)
                return value if isinstance(value, dict) else {}
        except Exception:  # a corrupt or foreign record: the bag then says nothing of its trial
            return {}
    finally:
        reader.close()
    return {}


def _guard(rules: tuple[str, ...], bag: str, robot_radius_mm: float | None, from_bag: bool = False):
    from ..guard.guard import Guard
    from ..contracts.components import RobotSpec
    from ..errors import SafeEmbodAIError
    from ..models import ControlLimits

    chosen: list[Any] = [_rule(r) for r in rules]
    robot, limits, source = RobotSpec(), None, "given" if chosen else "the Guard's defaults"
    # a bag is judged by the rules it recorded only when asked: otherwise it could choose its own judge
    trial = recorded_trial(bag) if from_bag else {}
    try:
        if not chosen and isinstance(trial.get("arm"), dict) and trial["arm"].get("safety_validation"):
            chosen, source = list(trial["arm"].get("validators") or []), "recorded in the bag"
        if isinstance(trial.get("robot"), dict):
            sizes: dict[str, Any] = {k: float(v) for k, v in trial["robot"].items()
                                     if k in ("radius_mm", "width_mm", "length_mm")}
            if not all(math.isfinite(v) and 0 < v <= 10_000 for v in sizes.values()):
                raise ValueError(f"robot sizes must be positive and finite millimetres, got {sizes}")
            robot = RobotSpec(**sizes)
        if isinstance(trial.get("limits"), dict):
            limits = ControlLimits.model_validate(trial["limits"])
    except (TypeError, ValueError) as error:
        raise SafeEmbodAIError(f"{bag}: /safeembodai/trial is unreadable: {error}") from None
    if robot_radius_mm is not None:
        robot = RobotSpec(radius_mm=robot_radius_mm, width_mm=2 * robot_radius_mm, length_mm=2 * robot_radius_mm)
    kwargs: dict[str, Any] = {"robot": robot}
    if limits is not None:
        kwargs["limits"] = limits
    if chosen:
        kwargs["rules"] = chosen
    try:
        return Guard(**kwargs), source
    except (TypeError, ValueError) as error:  # a rule given or recorded that is no validator's reference
        raise SafeEmbodAIError(f"rules ({source}) cannot be built: {error}") from None


@click.command("guard-bag")
@click.argument("bag", type=click.Path(exists=True))
@click.option("--scan", "scan_topic", default="/scan", show_default=True, help="sensor_msgs/LaserScan topic.")
@click.option("--cmd", "cmd_topic", default="/cmd_vel", show_default=True,
              help="Commands: geometry_msgs/Twist(Stamped), or std_msgs/String plans (/safeembodai/plan).")
@click.option("--pose", "pose_topic", default=None, help="geometry_msgs/PoseStamped topic: gives motion rules history.")
@click.option("--rules", multiple=True, metavar="RULE",
              help="A validator by name, or JSON {\"use\": ..., \"options\": {...}}; repeatable.")
@click.option("--mount", default=None, metavar="X_MM,Y_MM,YAW_DEG", help="The scanner's place on the robot.")
@click.option("--robot-radius-mm", type=click.FloatRange(min=1.0, max=5000.0), default=None,
              help="The robot's radius (default: as recorded in the bag, else 170).")
@click.option("--hold", "hold_s", type=click.FloatRange(min=0.0, min_open=True), default=None,
              help="Judge every Twist held this long (default: until the next command, at most --max-hold).")
@click.option("--max-hold", "max_hold_s", type=click.FloatRange(min=0.0, min_open=True), default=1.0,
              show_default=True, help="Longest a Twist counts as held when the next command is late or absent.")
@click.option("--min-hold", "min_hold_s", type=click.FloatRange(min=0.0, min_open=True), default=0.1,
              show_default=True, help="Shortest a Twist counts as held, however soon the next command comes.")
@click.option("--rules-from-bag", is_flag=True,
              help="Judge by the rules, robot size and limits the bag recorded (/safeembodai/trial of an exported "
                   "trial) when --rules is not given; without it a bag never chooses its own rules.")
@click.option("--limit", is_flag=True,
              help="Also report, per Twist, the fastest command along its path the guard would have allowed.")
@click.option("--json", "as_json", is_flag=True, help="One JSON document: a record per command and its verdict.")
def guard_bag(bag, scan_topic, cmd_topic, pose_topic, rules, mount, robot_radius_mm, hold_s, max_hold_s, min_hold_s,
              rules_from_bag, limit, as_json) -> None:
    """Judge every command recorded in BAG with the guard: which would it have refused, when, and why."""
    from ..guard.bag_guard import guard_bag as judge
    from ..ros.laser_scan import SensorMount

    sensor = None
    if mount is not None:
        try:
            x, y, yaw = (float(v) for v in mount.split(","))
            sensor = SensorMount(x, y, yaw)
        except ValueError as error:
            raise click.BadParameter(f"{mount!r}: {error} (expected X_MM,Y_MM,YAW_DEG)", param_hint="--mount") from None
    guard, source = _guard(rules, bag, robot_radius_mm, rules_from_bag)
    report = judge(bag, guard, scan_topic=scan_topic, cmd_topic=cmd_topic, pose_topic=pose_topic, mount=sensor,
                   hold_s=hold_s, max_hold_s=max_hold_s, min_hold_s=min(min_hold_s, max_hold_s), limit=limit)
    if as_json:
        click.echo(json.dumps({**report.as_dict(), "rules_from": source}, indent=1, allow_nan=False))
        return
    _print_table(report, source, limit)


def _print_table(report: Any, source: str, limit: bool = False) -> None:
    from rich.console import Console
    from rich.table import Table

    from ..trust.text import terminal_text

    console = Console(emoji=False)
    table = Table(title=f"{terminal_text(report.cmd_topic)} in {terminal_text(report.bag)}")
    for column in ("#", "time s", "command", "scan s", "verdict") + (("allowed",) if limit else ()):
        table.add_column(column)
    for v in report.verdicts:
        if v.kind == "twist":
            what = (f"v {v.command['linear_x']:+.2f} m/s, w {v.command['angular_z']:+.2f} rad/s "
                    f"for {v.command['duration_s']:.2f} s")
        else:
            control = v.command.get("control")
            what = "no plan" if control is None else f"plan of {len(control)} signal(s)"
        verdict = "ok" if v.valid else "REFUSED: " + "; ".join(v.reasons)
        if not v.valid and v.safe_duration_s is not None:
            verdict += f" (safe for {v.safe_duration_s:.2f} s)"
        scan = "-" if v.scan_time_s is None else f"{v.scan_time_s:.2f}"
        if not v.valid and v.collision_time_s is not None:
            verdict += f" (touch after {v.collision_time_s:.2f} s)"
        allowed = () if not limit else ("-" if v.allowed is None else (
            f"v {v.allowed['linear_x']:+.2f} m/s, w {v.allowed['angular_z']:+.2f} rad/s (x{v.allowed['factor']:.2f})"),)
        table.add_row(str(v.index), f"{v.time_s:.2f}", what, scan, terminal_text(verdict), *allowed)
    console.print(table)
    console.print(f"{len(report.refused)} of {len(report.verdicts)} commands refused; rules ({source}): "
                  f"{terminal_text(', '.join(report.rules))}")
