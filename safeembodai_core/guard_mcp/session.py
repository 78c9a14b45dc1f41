"""A guard-mcp session as a run folder that ``show``, ``report`` and ``view`` read.

Modelled on serve-robot's (:mod:`~safeembodai_core.serve_robot.session_record`): the session is one
trial, ``robot/guard-mcp/mcp/0``, of a scenario derived from the policy: the environment ``outside``
(the robot, reached over rosbridge, never simulated here), the backend ``outside`` with ``client: mcp``
(the calls came from an MCP client we did not ask), one arm ``guard-mcp`` with the defences the
policy turns on (safety validation always: ``command_limits`` and ``swept_body``) and one condition
``mcp``. The policy's own keys go in the scenario's description.

Every call is a step: ``instruction`` the call in words (a motion's messages and durations, or the
arguments as read; the agent's own text quoted where nothing could be read), one attempt whose
``verdicts`` are the guard's (by ``policy``, ``scan``, ``guard``, ``stop_only`` or ``upstream``, each
reason a verdict), ``executed`` what ran (the slices' motion as the straight or turn that names it
best, its result measured by odometry where there is one), the robot's odometry pose before and after
(when the call was answered: the base may hold the last message a little longer). Steps are written
by a thread of their own, so that a slow disk never holds a call up. :meth:`CallSession.finish` writes
the result when guard-mcp ends, whatever ends it: ``safe_abort`` when the refusals in a row left only
stops answered, else ``timeout`` with what ended it. Collisions are not guard-mcp's to know: the
robot's own record holds them (the result's detail says so).
"""

from __future__ import annotations

import math
import queue
import threading
import time
from pathlib import Path
from typing import TYPE_CHECKING

from ..runs.folder import RunFolder
from ..geometry.frames import wrap_deg
from ..logs import get_logger
from ..loop.defences import Defences
from ..models import Attempt, ExecutedSignal, ExecutionResult, LLMResponse, Outcome, Pose, StepRecord, TrialResult, \
    Verdict
from ..models.control import MAX_TEXT
from ..plugin.refs import ComponentRef
from ..scenario import Condition, Scenario
from ..runs.live_trial import LiveTrial
from ..serve_robot.session_record import held_signal

if TYPE_CHECKING:
    from ..plugin.manager import Plugins
    from .policy import Policy
    from .proxy import GuardMcp
    from .records import CallRecord

log = get_logger(__name__)
LABEL, ARM, CONDITION = "robot", "guard-mcp", "mcp"
#: Verdicts of a call the guard let through.
PASSED = ("read_only", "forwarded", "limited")


def session_scenario(policy: Policy, rosbridge: str, upstream: str) -> Scenario:
    """The scenario a guard-mcp session records (module docstring)."""
    arm = Defences(security_prefix=policy.security_prefix, state_management=policy.state_management,
                   safety_validation=True,
                   validators=[ComponentRef(use="command_limits"),
                               ComponentRef(use="swept_body", options={"margin_mm": policy.margin_mm})])
    words = (f"safeembodai guard-mcp in front of {upstream}: mode {policy.mode}, horizon {policy.horizon_s:g} s, "
             f"scan timeout {policy.scan_timeout_s:g} s, slices of {policy.slice_s:g} s, failures "
             f"{policy.failures.threshold} then {policy.failures.then}, untrusted results "
             f"{'marked' if policy.mark_untrusted else 'unmarked'}")
    return Scenario(name="guard-mcp", description=words, trials=1,
                    environments=[ComponentRef(use="outside", label=LABEL, options={"rosbridge": rosbridge})],
                    backend=ComponentRef(use="outside", options={"client": "mcp"}), arms={ARM: arm},
                    conditions={CONDITION: Condition()})


def _pose(pose: tuple[float, float, float] | None) -> Pose | None:
    return None if pose is None else Pose(x_mm=pose[0], y_mm=pose[1], heading_deg=pose[2])


def moved(before: tuple[float, float, float] | None,
          after: tuple[float, float, float] | None) -> tuple[float, float] | None:
    """``(distance_mm, angle_deg)`` odometry says the robot went between two poses (forward positive), or None."""
    if before is None or after is None:
        return None
    dx, dy = after[0] - before[0], after[1] - before[1]
    ahead = dx * math.cos(math.radians(before[2])) + dy * math.sin(math.radians(before[2]))
    return math.copysign(math.hypot(dx, dy), ahead), wrap_deg(after[2] - before[2])


def step_record(call: CallRecord, step: int, trial_id: str, started_s: float) -> StepRecord:
    """One call as a step (module docstring)."""
    reasons = call.reasons or [f"{call.verdict} by {call.by}"]
    if call.verdict in PASSED:
        ran = f"{len(call.ran)} slices" if call.ran else call.verdict.replace("_", "-")
        verdicts = [Verdict(rule=call.by, valid=True, reason="; ".join([ran, *call.reasons])[:MAX_TEXT])]
    else:
        verdicts = [Verdict(rule=call.by, valid=False, reason=reason[:MAX_TEXT]) for reason in reasons]
    words = call.words or f"{call.tool} {call.arguments}"
    attempt = Attempt(index=0, raw_text=f"{call.tool} {call.arguments}", verdicts=verdicts, latency_s=call.took_s,
                      response=LLMResponse(perception=[], planning=words[:MAX_TEXT], control=[]))
    executed = []
    if call.ran:
        commanded = (sum(x * s for x, _, s in call.ran) * 1000.0, math.degrees(sum(z * s for _, z, s in call.ran)))
        measured = moved(call.pose_before, call.pose_after)
        distance, angle = measured or commanded
        signal = held_signal(distance, angle) or held_signal(*commanded)
        odometry = (f"; odometry: {measured[0]:.0f} mm, {measured[1]:.1f} deg" if measured
                    else "; no odometry: as commanded")
        if signal is not None:
            result = ExecutionResult(distance_mm=distance, angle_deg=angle, stopped=call.verdict != "forwarded",
                                     detail=f"{call.result} (commanded {commanded[0]:.0f} mm, {commanded[1]:.1f} deg"
                                            f"){odometry}")
            executed.append(ExecutedSignal(signal=signal, result=result))
    return StepRecord(trial_id=trial_id, step=step, instruction=words, attempts=[attempt],
                      planned=[item.signal for item in executed], executed=executed, status="done",
                      accepted=call.verdict in PASSED, pose_before=_pose(call.pose_before),
                      pose_after=_pose(call.pose_after), sim_time_s=max(0.0, call.time_s - started_s))


class CallSession:
    """Writes a guard-mcp session's run folder as calls come (module docstring); :meth:`record` is the
    proxy's ``on_call`` and may be called from any thread."""

    def __init__(self, policy: Policy, plugins: Plugins, out: str | Path, *, rosbridge: str, upstream: str) -> None:
        self.scenario = session_scenario(policy, rosbridge, upstream)
        self.trial = LiveTrial(RunFolder.create(out, self.scenario), self.scenario, label=LABEL, arm=ARM,
                               condition=CONDITION)
        self.folder, self.spec = self.trial.folder, self.trial.spec
        self.store = self.trial.begin(plugins)
        self.started_s = time.time()
        self.steps = self.refused = 0
        self.distance_mm = 0.0
        self.poses: list[Pose] = []
        self.result: TrialResult | None = None
        self._queue: queue.Queue[CallRecord | None] = queue.Queue()
        self._writer = threading.Thread(target=self._write, name="guard-mcp-session", daemon=True)
        self._writer.start()

    @property
    def path(self) -> Path:
        return self.folder.path

    def record(self, call: CallRecord) -> None:
        """A call was answered: its step is written by the session's thread."""
        self._queue.put(call)

    def _write(self) -> None:
        while (call := self._queue.get()) is not None:
            self.steps += 1
            try:
                record = step_record(call, self.steps, self.spec.trial_id, self.started_s)
                self.store.record_step(record)
            except Exception as error:  # noqa: BLE001 - the record fails, the guard serves on; said once per call
                log.error("guard_mcp.session_unwritten", step=self.steps, error=repr(error)[:300])
                continue
            self.refused += not record.accepted
            self.distance_mm += sum(abs(item.result.distance_mm) for item in record.executed)
            if record.pose_after is not None:
                self.poses.append(record.pose_after)

    def finish(self, guard: GuardMcp | None = None, ended: str = "guard-mcp ended") -> None:
        """Write the steps still queued, the result (once), and close the store."""
        if self.result is not None:
            return
        self._queue.put(None)
        self._writer.join(30)
        stopped = guard.refusals_in_a_row if guard is not None and guard.stop_only else 0
        outcome = Outcome.SAFE_ABORT if stopped else Outcome.TIMEOUT
        detail = (f"{ended} after {self.steps} calls, {self.refused} refused"
                  + (f"; {stopped} refusals in a row left only stops answered" if stopped else "")
                  + "; collisions are the robot's own record's to tell, not guard-mcp's")
        self.result = TrialResult(spec=self.spec, outcome=outcome, steps=self.steps, distance_mm=self.distance_mm,
                                  interventions=self.refused, detail=detail, trajectory=self.poses, world="outside",
                                  wall_time_s=time.time() - self.started_s)
        try:
            self.trial.end(self.result)
        finally:
            self.trial.close()
        log.info("guard_mcp.session_finished", folder=str(self.path), calls=self.steps)

