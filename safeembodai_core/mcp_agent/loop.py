"""The agent's loop: step after step, a decider observes, decides and acts through the MCP tools.

:func:`run_agent` asks the trial for each step's input (:class:`StepInput`: the human instruction of
that step, an attacked one when the condition attacks it; the trial may also change the world, say
the text the camera will read) and hands it to a :class:`Decider`, which calls the read tools it
needs, decides, calls the motion tool and reads what came back -- a refusal's reasons and advice fed
back to it, Algorithm 1's retry -- and reports the step (:class:`StepReport`). The loop ends at the
first of: the room's outcome (``finished()``: a collision, the can reached, the room's time limit),
the step budget, the wall-clock limit, or a decider that gives up (``safe_abort``: its retries
spent, or the server answers only stops) or fails.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from typing import Awaitable, Callable, Literal, Protocol

from ..models import DEFAULT_LIMITS, Attempt, ControlLimits, ControlSignal
from ..models.prompt import DEFAULT_TASK
from .motions import Speeds
from .tools import McpTools

#: Why a run ended: the room decided, the step budget or the wall clock ran out, the decider gave up
#: (Algorithm 1's retries spent, or a server that answers only stops) or failed.
Ending = Literal["outcome", "steps", "time", "safe_abort", "error"]


@dataclass(frozen=True)
class Topics:
    """Where the robot's sensors and base are (the served room's names)."""

    scan: str = "/scan"
    camera: str = "/camera/image_raw/compressed"
    camera_text: str = "/camera/text"
    cmd_vel: str = "/cmd_vel"


@dataclass(frozen=True)
class AgentTask:
    """What the agent is told and bound by: the task, the robot's speeds and limits, where the robot is
    (``robot``: ``(host, port)`` to ``connect_to_robot`` first; None when the server points its
    upstream itself), its topics, the step budget, the wall-clock limit and Algorithm 1's retries."""

    task: str = DEFAULT_TASK
    limits: ControlLimits = DEFAULT_LIMITS
    speeds: Speeds = field(default_factory=Speeds)
    robot: tuple[str, int] | None = None
    topics: Topics = field(default_factory=Topics)
    max_steps: int = 20
    time_limit_s: float = 300.0
    failure_threshold: int = 3


@dataclass(frozen=True)
class StepInput:
    """Step ``step`` (from 1) of the trial seeded ``seed``: its human instruction."""

    step: int
    instruction: str
    seed: int


@dataclass
class StepReport:
    """What a step did: the decider's ``attempts`` (each with its parsed answer and the server's
    verdicts), the plan that ran (``planned``), the motions the server ``refused`` (with ``notes``: their
    reasons), what the camera read, and ``ended`` when the decider ends the run (``safe_abort``, or
    ``error`` with ``detail``)."""

    step: int
    instruction: str
    attempts: list[Attempt] = field(default_factory=list)
    planned: list[ControlSignal] = field(default_factory=list)
    refused: int = 0
    notes: list[str] = field(default_factory=list)
    camera_text: str = ""
    ended: Ending | None = None
    detail: str = ""
    started_s: float = 0.0


class Decider(Protocol):
    """Decides one step at a time, calling the tools itself."""

    async def begin(self, tools: McpTools, task: AgentTask) -> None:
        """Before the first step: the server's instructions and tools are known (``tools``)."""

    async def step(self, tools: McpTools, given: StepInput) -> StepReport:
        """Observe, decide, act and read the result for one step (module docstring)."""

    def close(self) -> None:
        """Release what the decider holds (a model's connections)."""


@dataclass
class AgentRun:
    """A run's steps and why it ended."""

    steps: list[StepReport] = field(default_factory=list)
    ending: Ending = "steps"
    detail: str = ""
    wall_s: float = 0.0


async def connect(tools: McpTools, task: AgentTask) -> None:
    """Point a server that is not pointed yet (ros-mcp direct) at the robot, as an agent told its address does."""
    if task.robot is None or not tools.has("connect_to_robot"):
        return
    outcome = await tools.call("connect_to_robot", {"ip": task.robot[0], "port": task.robot[1]})
    if outcome.error:
        raise ConnectionError(f"connect_to_robot failed: {outcome.text[:300]}")


async def run_agent(tools: McpTools, decider: Decider, task: AgentTask,
                    before_step: Callable[[int], Awaitable[StepInput]],
                    finished: Callable[[], bool]) -> AgentRun:
    """Run ``decider`` through ``tools`` until the run ends (module docstring)."""
    run, started = AgentRun(), time.monotonic()
    try:
        await connect(tools, task)
        await decider.begin(tools, task)
        for number in range(1, task.max_steps + 1):
            if finished():
                run.ending = "outcome"
                break
            if time.monotonic() - started >= task.time_limit_s:
                run.ending, run.detail = "time", f"the agent's wall-clock limit of {task.time_limit_s:g} s"
                break
            given = await before_step(number)
            report = await decider.step(tools, given)
            report.started_s = round(time.monotonic() - started, 3)
            run.steps.append(report)
            if report.ended is not None:
                run.ending, run.detail = report.ended, report.detail
                break
        else:
            run.ending = "outcome" if finished() else "steps"
            run.detail = "" if finished() else f"the step budget of {task.max_steps} was spent"
    except (ConnectionError, OSError) as error:
        run.ending, run.detail = "error", f"{type(error).__name__}: {error}"[:500]
    run.wall_s = time.monotonic() - started
    return run
