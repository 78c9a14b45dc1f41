"""``safeembodai guard-mcp --upstream-cmd "CMD ARGS" --rosbridge ws://HOST:PORT``: the guard in front of a
robot's MCP server (docs/guard_mcp.md)."""

from __future__ import annotations

import click


@click.command("guard-mcp")
@click.option("--upstream-cmd", "upstream_cmd", default=None, metavar='"CMD ARGS"',
              help="The upstream MCP server, started over stdio (ros-mcp's script, with its arguments).")
@click.option("--upstream-url", "upstream_url", default=None, metavar="URL",
              help="Or an upstream MCP server already running, over streamable HTTP (http://HOST:PORT/mcp).")
@click.option("--rosbridge", "rosbridge", required=True, metavar="ws://HOST:PORT",
              help="The robot's rosbridge: guard-mcp reads its scan and odometry there, and only this robot may "
                   "be reached through the upstream.")
@click.option("--policy", "policy_path", type=click.Path(dir_okay=False), default=None,
              help="The policy (YAML; docs/guard_mcp.md). Default: the shipped policy for ros-mcp 3.x.")
@click.option("--robot", "robot_path", type=click.Path(dir_okay=False), default=None,
              help="The robot file (YAML: body, scanners, limits, cmd_vel_timeout_s; docs/robot_file.md). Default: a "
                   "disc of 170 mm, one scanner at the centre on /scan whose null ranges are unknown.")
@click.option("--transport", type=click.Choice(["stdio", "http"]), default="stdio", show_default=True,
              help="How the agent's MCP client reaches guard-mcp (http: streamable HTTP on 127.0.0.1).")
@click.option("--port", type=click.IntRange(1, 65535), default=8765, show_default=True,
              help="The HTTP port (with --transport http).")
@click.option("--out", "out", type=click.Path(file_okay=False), default="runs", show_default=True,
              help="Where the session's run folder goes (every call, its verdict, what ran; show and view read it).")
def guard_mcp(upstream_cmd, upstream_url, rosbridge, policy_path, robot_path, transport, port, out) -> None:
    """Guard a robot's MCP server: the upstream's tools, each call that can move the robot judged on the
    robot's own scan, everything else that actuates refused unless the policy allows it."""
    from .. import Guard
    from ..errors import SafeEmbodAIError

    try:
        import anyio
        import mcp  # noqa: F401
    except ImportError:
        raise SafeEmbodAIError("guard-mcp needs the MCP SDK: pip install -e \".[mcp]\"") from None
    from ..guard_mcp.policy import read_policy
    from ..guard_mcp.server import robot_address, serve
    from ..ros.robot_file import RobotFile, read_robot_file

    if (upstream_cmd is None) == (upstream_url is None):
        raise SafeEmbodAIError("give the upstream as --upstream-cmd or as --upstream-url, exactly one of them")
    robot_address(rosbridge)
    policy = read_policy(policy_path)
    robot = read_robot_file(robot_path) if robot_path else RobotFile(radius_mm=170.0)
    guard = Guard(["command_limits", {"use": "swept_body", "options": {"margin_mm": policy.margin_mm}}],
                  robot=robot.robot_spec())
    try:
        anyio.run(lambda: serve(policy, robot, guard, rosbridge=rosbridge, upstream_cmd=upstream_cmd,
                                upstream_url=upstream_url, transport=transport, port=port, out=out))
    except Exception as error:  # the task groups of anyio and the MCP SDK wrap what failed in exception groups
        found = _own_error(error)
        if found is None:
            raise
        raise found from None


def _own_error(error: BaseException) -> BaseException | None:
    """The project's own error, ``error`` or inside its exception groups (said without a traceback), or None."""
    from ..errors import SafeEmbodAIError

    if isinstance(error, SafeEmbodAIError):
        return error
    for inner in getattr(error, "exceptions", ()):
        found = _own_error(inner)
        if found is not None:
            return found
    return None
