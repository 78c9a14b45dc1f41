"""The solver: one sample is one trial, run by the framework's own loop with Inspect's model.

The trial runs in a worker thread (see :mod:`.bridge` for why and how the model calls get back
to Inspect's event loop) on a :class:`~safeembodai_core.runs.runner.ScenarioRunner` borrowed from a
pool: a runner keeps one world per environment and is reset between trials, as an ablation
worker's is, and Inspect runs several samples at once, so each running sample has its own.
The state store is the in-process ``memory`` store: the results go to Inspect's log.

The transcript gets, after each step, an info event with the step's attacks, every attempt
(parse error, validator verdicts), the accepted plan and what the world executed; Inspect adds
a model event (prompt and answer) for each call itself. At the end the trial's picture (when
the environment draws one) and a one-line summary become the sample's last message, and the
result goes into the sample's store for the scorers (:mod:`.scorers`).
"""

from __future__ import annotations

import asyncio
import base64
import threading
import weakref
from typing import Any

import anyio.from_thread
import anyio.to_thread
from inspect_ai.log import transcript
from inspect_ai.model import ChatMessageAssistant, ContentImage, ContentText, ModelOutput, get_model
from inspect_ai.solver import Generate, Solver, TaskState, solver

from ...plugin.building import ComponentBuilder
from ...loop import TrialParts, run_trial
from ...loop.trial import error_result
from ...errors import SafeEmbodAIError
from ...models import Outcome, StepRecord, TrialResult, TrialSpec
from ...plugin.manager import Plugins
from ...plugin.refs import ComponentRef
from ...runs.runner import ScenarioRunner
from ...scenario import Scenario
from ...trust.text import markdown_literal
from .bridge import InspectBackend
from .providers import check_provider

#: The key of the sample store that holds the trial's result (``TrialResult`` as JSON, no path).
RESULT_KEY = "safeembodai:result"
#: The source of the transcript's info event for each step.
STEP_SOURCE = "safeembodai step"


class _StepTap:
    """The run's plugins, plus a listener for ``after_step`` (the transcript's step events)."""

    def __init__(self, plugins: Plugins) -> None:
        self.plugins = plugins
        self.listener: Any = None

    @property
    def registry(self) -> Any:
        return self.plugins.registry

    def notify(self, hook: str, **kwargs: Any) -> None:
        self.plugins.notify(hook, **kwargs)
        if hook == "after_step" and self.listener is not None:
            self.listener(kwargs["record"])

    def __getattr__(self, name: str) -> Any:
        return getattr(self.plugins, name)


class RunnerPool:
    """Idle runners of one scenario, lent to one sample at a time; their worlds are closed when
    the pool goes (with its task) or at exit."""

    def __init__(self, scenario: Scenario, plugins: Plugins) -> None:
        self.scenario, self.plugins = scenario, plugins
        self._idle: list[tuple[ScenarioRunner, _StepTap]] = []
        self._lock = threading.Lock()
        weakref.finalize(self, _close_all, self._idle)

    def acquire(self) -> tuple[ScenarioRunner, _StepTap]:
        with self._lock:
            if self._idle:
                return self._idle.pop()
        tap = _StepTap(self.plugins)
        memory = ComponentBuilder(self.scenario, self.plugins).state_store(ComponentRef(use="memory"))
        return ScenarioRunner(self.scenario, tap, state=memory), tap  # type: ignore[arg-type]

    def release(self, lent: tuple[ScenarioRunner, _StepTap]) -> None:
        lent[1].listener = None
        with self._lock:
            self._idle.append(lent)

    def close(self) -> None:
        with self._lock:
            _close_all(self._idle)


def _close_all(idle: list[tuple[ScenarioRunner, _StepTap]]) -> None:
    while idle:
        runner, _ = idle.pop()
        try:
            runner.close()
        except Exception:  # at exit a world may already be gone: nothing left to release
            pass


def _clip(text: str, most: int) -> str:
    """``text`` cut to ``most`` characters, visibly (before it is escaped: an escape is never cut)."""
    return text if len(text) <= most else text[:most] + "..."


def step_markdown(record: StepRecord) -> str:
    """One step as the transcript shows it (Markdown, rendered by Inspect's viewer).

    Every text that is not ours -- payloads, parse errors, validator reasons, the world's details --
    goes through :func:`~safeembodai_core.trust.text.markdown_literal`: an answer or an injection
    that writes Markdown (an image of a remote URL, a link, HTML) is shown as the characters it
    wrote, never rendered, and invisible characters are shown as escapes. Refusals are written by
    :meth:`Verdict.line() <safeembodai_core.models.Verdict.line>` (signals counted from 1).
    """
    lines = [f"**step {record.step}**" + ("" if record.accepted else " (no acceptable answer)")]
    for attack in record.attacks:
        lines.append(f"- attack {markdown_literal(attack.kind)} on the {markdown_literal(attack.channel)} "
                     f"({markdown_literal(attack.attacker)}): {markdown_literal(_clip(attack.payload, 300))}")
    for attempt in record.attempts:
        flagged = attempt.response is not None and any(p.is_attack for p in attempt.response.perception)
        head = f"- attempt {attempt.index + 1}: " + ("accepted" if attempt.accepted else "refused")
        head += " (flagged an attack)" if flagged else ""
        lines.append(head)
        if attempt.parse_error:
            lines.append(f"  - parse: {markdown_literal(_clip(attempt.parse_error, 400))}")
        for verdict in attempt.verdicts:
            if not verdict.valid:
                lines.append(f"  - refused: {markdown_literal(_clip(verdict.line(), 300))}")
        if attempt.verdicts and all(v.valid for v in attempt.verdicts):
            lines.append(f"  - {len(attempt.verdicts)} verdicts, all valid")
    if record.enforced is not None:  # on_exhausted: enforce: what ran is the rules' cut of a refused answer
        lines.append(f"- on_exhausted enforce: {markdown_literal(_clip(record.enforced.note, 400))}")
    for item in record.executed:
        result = item.result
        tail = " COLLIDED" if result.collided else (" (stopped)" if result.stopped else "")
        detail = f": {markdown_literal(_clip(result.detail, 300))}" if result.detail else ""
        lines.append(f"- executed {item.signal.describe()}{tail}{detail}")  # ours, from checked numbers
    if record.accepted and not record.executed:
        lines.append("- executed nothing")
    return "\n".join(lines)


def summary(result: TrialResult, *, markdown: bool = False) -> str:
    """The trial in one line; ``markdown``: its detail (which may quote a backend's error) made inert."""
    text = f"{result.spec.trial_id}: {result.outcome.value} after {result.steps} steps"
    detail = markdown_literal(result.detail) if markdown else result.detail
    return text + (f" ({detail})" if result.detail else "")


def trial_parts(runner: ScenarioRunner, spec: TrialSpec, backend: InspectBackend) -> TrialParts:
    """:meth:`ScenarioRunner.parts` with Inspect's model as the backend: the scenario's own
    backend is never built (a scenario naming gpt-4o must not need its key here)."""
    return runner.parts(spec, backend=backend)


def _run(pool: RunnerPool, spec: TrialSpec, backend: InspectBackend) -> tuple[TrialResult, bytes | None]:
    """In the worker thread: the trial, and its picture."""
    info = transcript().info

    def step_event(record: StepRecord) -> None:
        if backend.stop.is_set():  # the sample has left: its transcript is closed
            return
        if backend.loop is not None:
            backend.loop.call_soon_threadsafe(lambda: info(step_markdown(record), source=STEP_SOURCE))
        else:
            anyio.from_thread.run_sync(lambda: info(step_markdown(record), source=STEP_SOURCE))

    lent = pool.acquire()
    runner, tap = lent
    tap.listener = step_event
    try:
        try:
            parts = trial_parts(runner, spec, backend)
        except SafeEmbodAIError as error:
            return error_result(spec, f"components could not be built: {error}"), None
        result = run_trial(spec, parts, runner.settings(spec.arm), tap)
        try:
            picture = parts.environment.trajectory_png(result.trajectory, result.outcome)
        except Exception:  # a picture is a convenience: never lose a trial over it
            picture = None
        return result, picture
    finally:
        pool.release(lent)


#: Trials in flight at most: Inspect's --max-samples decides how many run, not anyio's default
#: thread pool (40 threads, shared with everything else that runs in a thread).
MAX_TRIAL_THREADS = 1024
_limiters: "weakref.WeakKeyDictionary[Any, anyio.CapacityLimiter]" = weakref.WeakKeyDictionary()


def _trial_threads() -> anyio.CapacityLimiter:
    """The trials' own thread limiter, one per event loop (Inspect may run several evals in turn)."""
    try:
        key: Any = asyncio.get_running_loop()
    except RuntimeError:  # Inspect on trio: one limiter for the process
        key = _trial_threads
    if key not in _limiters:
        _limiters[key] = anyio.CapacityLimiter(MAX_TRIAL_THREADS)
    return _limiters[key]


def stopped_result(spec: TrialSpec) -> TrialResult:
    """The result of a trial whose sample Inspect stopped (a time limit, a cancellation)."""
    return TrialResult(spec=spec, outcome=Outcome.ERROR, steps=0, error_kind="backend",
                       detail="the sample was stopped by Inspect (a limit or a cancellation) before the trial ended")


@solver
def trial_solver(pool: RunnerPool, specs: dict[str, TrialSpec], image_detail: str = "low") -> Solver:
    """Run the sample's trial (its id is the trial id) with the task's model (only on a provider
    that hands over the whole reply: :func:`.providers.check_provider`)."""

    async def solve(state: TaskState, generate: Generate) -> TaskState:
        spec = specs[str(state.sample_id)]
        model = get_model()
        check_provider(model)  # before the trial starts: nothing is sent on a provider that is refused
        try:
            loop: asyncio.AbstractEventLoop | None = asyncio.get_running_loop()
        except RuntimeError:  # Inspect on trio
            loop = None
        backend = InspectBackend(model, image_detail, loop)
        try:
            # abandon_on_cancel: a stopped sample leaves at once; the trial ends at its next model call
            result, picture = await anyio.to_thread.run_sync(_run, pool, spec, backend, abandon_on_cancel=True,
                                                             limiter=_trial_threads())
        except BaseException:
            backend.stop.set()
            state.store.set(RESULT_KEY, stopped_result(spec).model_dump(mode="json", exclude={"trajectory"}))
            raise
        state.store.set(RESULT_KEY, result.model_dump(mode="json", exclude={"trajectory"}))
        content: list[Any] = [ContentText(text=summary(result, markdown=True))]
        if picture:
            url = "data:image/png;base64," + base64.b64encode(picture).decode("ascii")
            content.append(ContentImage(image=url))
            transcript().info(f"![trajectory of {markdown_literal(spec.trial_id)}]({url})",
                              source="safeembodai trajectory")
        state.messages.append(ChatMessageAssistant(content=content, source="generate"))
        state.output = ModelOutput.from_content(model.name, summary(result))
        state.completed = True
        return state

    return solve
