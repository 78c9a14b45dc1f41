"""An ablation of an MCP agent driving served rooms: every trial of every cell, in one run folder.

:meth:`McpAblation.prepare` checks everything before any folder is made: the MCP SDK, ros-mcp's
script, every arm's route and every condition's attackers (:mod:`.cells`), and the decider (its
components build). :meth:`McpAblation.run` then runs the trials one at a time, cell by cell, in trial
order (each has a room, a server and an agent of its own: trials do not share a port or a process),
and writes the run folder ``safeembodai report`` reads:

* ``scenario.json`` and the scenario's state store: one
  :class:`~safeembodai_core.models.TrialResult` and the :class:`~safeembodai_core.models.StepRecord`
  of every agent step per trial -- so ``report``, ``show`` and ``view`` read it like any run;
* ``trajectories/``: each trial's path, as its room drew it;
* ``trials/<trial>/``: the room's own run folder (the judge: every command it received and what it
  drove), the server's stderr (``server.log``), and guard-mcp's policy and robot file for that arm;
* ``transcripts/<trial>.jsonl``: every tool call the agent made and what came back;
* ``agent.json``: the decider, the ros-mcp script and the arms' routes;
* ``report.md``, ``metrics.csv``, ``metrics.json`` and ``figures/``: the project's report.

Nothing is resumed: a run stopped midway keeps the trials it finished (``report`` reads them).
"""

from __future__ import annotations

import json
import os
import shutil
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Callable

from ..runs.folder import RunFolder, RunLock
from ..plugin.building import ComponentBuilder
from ..contracts.components import StateStore
from ..errors import SafeEmbodAIError
from ..models import TrialResult, TrialSpec
from ..plugin.manager import Plugins
from ..runs.files import trial_file_name
from ..runs.runner import trial_spec
from ..scenario import Scenario
from ..runs.trial_files import trajectory_file
from .cells import Route, check
from .deciders import decider_factory
from .loop import Decider
from .trial import TrialRecord, run_mcp_trial

ROS_MCP_INSTALL = ("ros-mcp runs from a virtual environment of its own: python -m venv ros-mcp-venv && "
                   "ros-mcp-venv/bin/pip install ros-mcp==3.1.2, then --ros-mcp ros-mcp-venv/bin/ros-mcp "
                   "(or SAFEEMBODAI_ROS_MCP)")


def find_ros_mcp(given: str | None) -> str:
    """ros-mcp's script: ``given``, else ``SAFEEMBODAI_ROS_MCP``, else ``ros-mcp`` on PATH."""
    found = given or os.environ.get("SAFEEMBODAI_ROS_MCP") or shutil.which("ros-mcp")
    if not found:
        raise SafeEmbodAIError(f"ros-mcp was not found: {ROS_MCP_INSTALL}")
    path = Path(found).expanduser()
    if not (path.is_file() and os.access(path, os.X_OK)):
        raise SafeEmbodAIError(f"{found} is not an executable file: {ROS_MCP_INSTALL}")
    return str(path.resolve())


@dataclass
class McpAblation:
    """A checked plan of trials (module docstring)."""

    scenario: Scenario
    plugins: Plugins
    routes: dict[str, Route]
    ros_mcp: str
    decider: str
    make_decider: Callable[[TrialSpec], Decider]

    @classmethod
    def prepare(cls, scenario: Scenario, plugins: Plugins, *, ros_mcp: str | None = None,
                decider: str = "pilot") -> "McpAblation":
        try:
            import mcp  # noqa: F401
        except ImportError:
            raise SafeEmbodAIError("the MCP agent needs the MCP SDK: pip install -e \".[mcp]\"") from None
        routes = check(scenario, plugins)
        script = find_ros_mcp(ros_mcp)
        return cls(scenario, plugins, routes, script, decider, decider_factory(decider, scenario, plugins))

    def specs(self) -> list[TrialSpec]:
        """Every trial, cell by cell, in the scenario's order."""
        s = self.scenario
        return [trial_spec(s, e, a, c, k) for (e, a, c) in s.cells() for k in range(s.trials)]

    def run(self, out_root: str | Path, on_result: Callable[[TrialResult], None] = lambda result: None,
            report: bool = True) -> tuple[Path, list[TrialResult], Path | None]:
        """Run every trial into a new run folder under ``out_root``: (its path, the results, the report)."""
        folder = RunFolder.create(out_root, self.scenario)
        folder.start(self.scenario)
        lock = RunLock(folder.path, wait_s=0.0)
        lock.acquire()
        store = ComponentBuilder(self.scenario, self.plugins, run_dir=folder.path).state_store()
        results: list[TrialResult] = []
        try:
            self._describe(folder.path)
            for spec in self.specs():
                record = run_mcp_trial(spec, self.scenario, self.plugins, self.routes[spec.arm], ros_mcp=self.ros_mcp,
                                       folder=folder.path / "trials" / trial_file_name(spec.trial_id),
                                       decider=self.make_decider)
                self._keep(folder, store, record)
                results.append(record.result)
                on_result(record.result)
            written = None
            if report and results:
                from ..report import write_report

                written = write_report(folder.path, self.scenario, results, store=store, plugins=self.plugins)
            return folder.path, results, written
        finally:
            store.close()
            lock.release()

    def _describe(self, path: Path) -> None:
        about = {"decider": self.decider, "ros_mcp": self.ros_mcp,
                 "routes": {arm: asdict(route) for arm, route in self.routes.items()}}
        (path / "agent.json").write_text(json.dumps(about, indent=2), encoding="utf-8")

    @staticmethod
    def _keep(folder: RunFolder, store: StateStore, record: TrialRecord) -> None:
        spec = record.result.spec
        store.begin_trial(spec)
        for step in record.steps:
            store.record_step(step)
        store.end_trial(record.result)
        folder.note_finished([spec.trial_id])
        transcripts = folder.path / "transcripts"
        transcripts.mkdir(exist_ok=True)
        (transcripts / f"{trial_file_name(spec.trial_id)}.jsonl").write_text(
            "".join(json.dumps(call) + "\n" for call in record.transcript), encoding="utf-8")
        pictures = sorted(record.room_folder.glob("trajectories/*.png")) if record.room_folder else []
        if pictures:
            target = trajectory_file(folder.path, spec.trial_id)
            target.parent.mkdir(parents=True, exist_ok=True)
            shutil.copyfile(pictures[0], target)
