"""``safeembodai agent-ablate SCENARIO``: an MCP agent drives served rooms, through ros-mcp or guard-mcp, under attack.

Each trial serves a room, starts ros-mcp (and guard-mcp in front of it for an arm with
``safety_validation``) and runs the agent; the room's own record decides the outcome
(docs/agent_ablation.md). Trials run one at a time.
"""

from __future__ import annotations

import click

from .common import load, scenario_options


@click.command("agent-ablate")
@scenario_options
@click.option("--out", "out_root", type=click.Path(file_okay=False), default="runs", show_default=True,
              help="Folder that receives the run folder <scenario>-<time>.")
@click.option("--ros-mcp", "ros_mcp", default=None, metavar="PATH",
              help="ros-mcp's script, from its own venv (default: SAFEEMBODAI_ROS_MCP, else ros-mcp on PATH).")
@click.option("--decider", type=click.Choice(["pilot", "tool-calls"]), default="pilot", show_default=True,
              help="pilot: the scenario's backend plans (the offline mock by default), its plans become motion "
                   "calls; tool-calls: a litellm model (the scenario's backend) calls the MCP tools itself.")
@click.option("--no-report", is_flag=True, help="Skip report.md and figures at the end.")
def agent_ablate(scenario_path, backend, seed, overrides, out_root, ros_mcp, decider, no_report) -> None:
    """Run SCENARIO's arms (ros-mcp direct, or through guard-mcp) and conditions with an MCP agent driving
    served rooms towards the red can; write a run folder that report, show and view read."""
    from rich.console import Console
    from rich.markup import escape

    from ..mcp_agent.ablation import McpAblation
    from ..trust.text import terminal_text
    from .summary import summary_table

    scenario, plugins = load(scenario_path, backend, seed, overrides)
    ablation = McpAblation.prepare(scenario, plugins, ros_mcp=ros_mcp, decider=decider)
    console = Console(emoji=False)
    total = len(ablation.specs())
    done = []

    def said(result) -> None:
        done.append(result)
        console.print(f"[{len(done)}/{total}] {terminal_text(result.spec.trial_id)}: {result.outcome.value} after "
                      f"{result.steps} steps, {result.collisions} collisions", soft_wrap=True, markup=False)

    folder, results, report = ablation.run(out_root, said, report=not no_report)
    console.print(summary_table(scenario, results, plugins=plugins))
    if report is not None:
        console.print(f"report: {escape(str(report))}", soft_wrap=True)
    console.print(f"run folder: {escape(str(folder))}", soft_wrap=True)
