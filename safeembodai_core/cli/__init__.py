"""The ``safeembodai`` command line: one module per command, plugins may add their own.

Errors a user can cause print one clear message and exit non-zero; ``--debug`` adds the
traceback. Nothing heavy (litellm, pybullet, cv2) is imported until a command needs it.

``SAFEEMBODAI_TRACE_PLUGINS=1`` shows every hook call whatever ``--log-level`` is: asking for the
trace is asking to see it.
"""

from __future__ import annotations

import os
import sys
import traceback

import click

from ..errors import PluginError, SafeEmbodAIError


class PluginAwareGroup(click.Group):
    """A group that asks plugins for extra commands the first time commands are listed."""

    _plugins_added = False
    plugin_error: PluginError | None = None

    def _add_plugin_commands(self) -> None:
        if self._plugins_added:
            return
        self._plugins_added = True
        from ..plugin.manager import load_plugins

        try:
            load_plugins().add_commands(self)
        except PluginError as error:  # the commands that need plugins will report it
            self.plugin_error = error

    def list_commands(self, ctx: click.Context) -> list[str]:
        self._add_plugin_commands()
        return super().list_commands(ctx)

    def get_command(self, ctx: click.Context, name: str) -> click.Command | None:
        command = super().get_command(ctx, name)
        if command is None:
            self._add_plugin_commands()
            command = super().get_command(ctx, name)
        return command


@click.group(cls=PluginAwareGroup, context_settings={"help_option_names": ["-h", "--help"]})
@click.option("--debug", is_flag=True, help="Show tracebacks and debug logs.")
@click.option("--log-level", default="warning", show_default=True,
              type=click.Choice(["debug", "info", "warning", "error"]), help="Log level (stderr).")
@click.option("--log-json", is_flag=True, help="Log JSON lines instead of text.")
@click.version_option(package_name="safeembodai")
@click.pass_context
def cli(ctx: click.Context, debug: bool, log_level: str, log_json: bool) -> None:
    """SafeEmbodAI: keep LLM-controlled mobile robots safe, and measure how much each defence buys."""
    from ..logs import configure_logging

    level = "debug" if debug else log_level
    configure_logging(level, log_json)
    if os.environ.get("SAFEEMBODAI_TRACE_PLUGINS") and level != "debug":
        _show_plugin_traces(level)
    ctx.obj = {"debug": debug}


def _show_plugin_traces(level: str) -> None:
    """Let the plugin manager's ``hook.call`` debug events through; other events keep ``level``."""
    import logging

    import structlog
    from structlog.typing import EventDict, WrappedLogger

    threshold = getattr(logging, level.upper())
    names = {"debug": logging.DEBUG, "info": logging.INFO, "warning": logging.WARNING, "warn": logging.WARNING,
             "error": logging.ERROR, "exception": logging.ERROR, "critical": logging.CRITICAL}

    def keep(logger: WrappedLogger, method: str, event: EventDict) -> EventDict:
        if event.get("event") != "hook.call" and names.get(method, logging.CRITICAL) < threshold:
            raise structlog.DropEvent
        return event

    structlog.configure(processors=[keep, *structlog.get_config()["processors"]],
                        wrapper_class=structlog.make_filtering_bound_logger(logging.DEBUG))


def _register_builtin_commands() -> None:
    from .ablate_cmd import ablate
    from .agent_ablate_cmd import agent_ablate
    from .export_cmd import export
    from .guard_bag_cmd import guard_bag
    from .guard_mcp_cmd import guard_mcp
    from .guard_node_cmd import guard_node
    from .plugins_cmd import plugins
    from .report_cmd import report
    from .run_cmd import run
    from .serve_robot_cmd import serve_robot
    from .view_cmd import view

    for command in (plugins, run, ablate, report, export, guard_bag, view, serve_robot, guard_node, guard_mcp,
                    agent_ablate):
        cli.add_command(command)


_register_builtin_commands()


def main(argv: list[str] | None = None) -> None:
    """Console-script entry point."""
    args = sys.argv[1:] if argv is None else list(argv)
    debug = "--debug" in args
    try:
        code = cli.main(args=args, prog_name="safeembodai", standalone_mode=False)
    except click.exceptions.Exit as done:
        code = done.exit_code
    except click.ClickException as error:
        error.show()
        code = error.exit_code
    except click.Abort:
        click.echo("Aborted.", err=True)
        code = 130
    except KeyboardInterrupt:
        click.echo("Interrupted.", err=True)
        code = 130
    except SafeEmbodAIError as error:
        if debug:
            traceback.print_exc()
        from ..trust.text import terminal_text  # an error may quote a bag's topic, a file name, a server

        click.echo(f"Error: {terminal_text(str(error), keep_layout=True)}", err=True)
        code = error.exit_code
    sys.exit(code if isinstance(code, int) else 0)
