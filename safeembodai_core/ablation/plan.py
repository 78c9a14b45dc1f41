"""One front door for a run: the scenario, its plugins, the executor and the run folder, each check once.

Every way in -- ``safeembodai ablate`` and ``run``, a library user's :class:`~.engine.Ablation`, the
Inspect task, the Gymnasium env -- reads its scenario through :func:`checked_scenario`; every way that
runs an ablation, and ``safeembodai run``'s one trial, goes through :meth:`RunPlan.prepare`, which runs
the checks below once, in this order, and before anything is written (a refused run leaves no folder):

1. options the executor would ignore (``--workers 2 --executor serial``, ``--address`` without Ray);
2. the scenario and its plugins: every component exists and its options validate, the metric
   catalog has no clash (:func:`checked_scenario`); resuming, the folder recorded the same scenario,
   its ``trajectories`` is a folder, and the state store keeps results across runs;
3. ``--executor ray``: the cluster answers (the address it found is named in the run's header);
4. the backend can work: it is built (a missing key fails its factory) and its own ``preflight()``
   runs (a litellm server must accept a connection); it suggests how many trials to keep in flight;
5. the executor can run the scenario: no inline plugin for worker processes, a persistent state store
   (asked once, of a store built in a scratch folder);
6. ``--max-cost``: the backend can say its price; ``--rerun``: the ``rerun`` extra is installed.

:meth:`Ablation.start(plan) <.engine.Ablation.start>` then makes (or, resuming, opens) the run
folder and hands back the :class:`~.engine.Ablation`, which checks nothing again.
"""

from __future__ import annotations

import tempfile
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

from ..plugin.building import ComponentBuilder
from ..errors import SafeEmbodAIError
from ..logs import get_logger
from ..plugin.manager import Plugins
from ..scenario import Scenario
from ..scenario.reading import checked_scenario
from ..runs.trial_files import ArtefactSettings

if TYPE_CHECKING:
    from .spending import SpendingCap

log = get_logger(__name__)

EXECUTORS = ("serial", "process", "ray")


class AblationError(SafeEmbodAIError):
    """The ablation cannot start or continue (the message says how to resume)."""


def executor_name(workers: int = 1, executor: str | None = None, address: str | None = None,
                  concurrency: int = 1) -> str:
    """The executor the options choose; options it would ignore are refused in one line.

    Trials run at once in threads (``concurrency`` > 1) run in worker processes, even with one
    worker: pybullet's chatter is silenced through the process-wide descriptors 1 and 2, which the
    coordinator's progress display and logs need."""
    if workers < 1:
        raise AblationError("--workers must be at least 1")
    if concurrency < 1:
        raise AblationError("--concurrency must be at least 1")
    name = executor or ("process" if workers > 1 or concurrency > 1 else "serial")
    if name not in EXECUTORS:
        raise AblationError(f"unknown executor {name!r}; choose serial, process or ray")
    if name == "serial" and (workers > 1 or concurrency > 1):
        option = f"--workers {workers}" if workers > 1 else f"--concurrency {concurrency}"
        raise AblationError(f"--executor serial runs one trial at a time, not {option}: "
                            f"drop {option.split()[0]}, or use --executor process or ray")
    if address is not None and name != "ray":
        raise AblationError(f"--address is the address of a Ray cluster: use it with --executor ray "
                            f"(the {name} executor would ignore it)")
    return name


def store_is_persistent(scenario: Scenario, plugins: Plugins) -> bool:
    """Whether the scenario's store keeps records across processes, asked of a store built in a
    scratch folder (so nothing appears in the run folder, which does not exist yet)."""
    with tempfile.TemporaryDirectory(prefix="safeembodai-store-check-") as scratch:
        store = ComponentBuilder(scenario, plugins, run_dir=scratch).state_store()
        try:
            return bool(store.persistent)
        finally:
            store.close()


def not_persistent(executor: str, scenario: Scenario) -> AblationError:
    return AblationError(f"--workers/--concurrency/--executor {executor} needs a persistent state store "
                         f"(e.g. sqlite); the scenario uses {scenario.state.use!r}")


@dataclass
class RunPlan:
    """A run whose every check passed (:meth:`prepare`); :meth:`Ablation.start <.engine.Ablation.start>`
    starts it."""

    scenario: Scenario
    plugins: Plugins
    executor: str
    workers: int = 1
    concurrency: int = 1
    address: str | None = None
    connect_timeout_s: float | None = None
    #: the Ray cluster connected to, for the run's header line (None: not Ray)
    where: str | None = None
    bags: str | None = None
    recordings: bool = False
    #: the response cache settings (a :class:`~..loop.response_cache.CacheSettings`; None: the run
    #: folder's default on a new run, what it recorded on a resume)
    cache: Any = None
    cap: "SpendingCap | None" = None
    #: the run folder this plan finishes (None: a new run)
    resume: str | Path | None = None
    #: whether the store keeps records across processes (asked once, in check 5)
    persistent: bool | None = field(default=None, repr=False)

    @classmethod
    def prepare(cls, scenario: Scenario, plugins: Plugins, *, workers: int = 1, concurrency: int | None = None,
                executor: str | None = None, address: str | None = None, connect_timeout_s: float | None = None,
                bags: str | None = None, recordings: bool = False, cache: Any = None,
                max_tokens: int | None = None, max_cost: float | None = None, warm_workers: bool = False,
                scenario_checked: bool = False, resume: str | Path | None = None) -> "RunPlan":
        """Run checks 1 to 6 (the module docstring) on ``scenario``; ``concurrency`` None takes the
        backend's suggestion where the run can take it. ``warm_workers`` starts the worker processes'
        fork server while the checks run (when the run will likely use it). ``scenario_checked``: the
        caller read it through :func:`checked_scenario` or :func:`recorded_scenario` already.
        ``resume``: the run folder to finish (the recordings it asked for need the extra too)."""
        executor_name(workers, executor, address, concurrency or 1)  # 1
        if not scenario_checked:
            scenario, plugins = checked_scenario(scenario, plugins)  # 2
        if resume is not None:
            check_resumable(Path(resume), scenario, plugins)  # 2
        where = cls._connect_ray(address, connect_timeout_s) if executor == "ray" else None  # 3
        if warm_workers:
            _warm_workers_early(scenario, plugins, workers, executor, concurrency)
        from ..runs.runner import preflight

        suggested = preflight(scenario, plugins)  # 4
        plan = cls(scenario, plugins, executor="", workers=workers, address=address,
                   connect_timeout_s=connect_timeout_s, where=where, bags=bags, recordings=recordings, cache=cache,
                   resume=resume, persistent=True if resume is not None else None)  # resuming: asked at 2
        plan.concurrency = concurrency if concurrency is not None else plan._default_concurrency(executor, suggested)
        plan.executor = plan._check_executor(executor)  # 5
        plan.cap = _spending_cap(scenario, plugins, max_tokens, max_cost)  # 6
        if recordings or (resume is not None and ArtefactSettings.recorded(resume).recordings):
            from ..runs.rerun_recording import import_rerun

            import_rerun()
        return plan

    @staticmethod
    def _connect_ray(address: str | None, timeout_s: float | None) -> str:
        """The Ray cluster answers (the ray extra is installed); returns the address connected to."""
        from .ray_executor import CONNECT_TIMEOUT_S, _ray, connect

        ray = _ray()
        connected = connect(ray, address, timeout_s or CONNECT_TIMEOUT_S)
        if address == "auto":  # whatever Ray found (RAY_ADDRESS, a cluster started here) is named in the header
            connected = f"auto: {ray.get_runtime_context().gcs_address}"
        return connected

    def _store_persistent(self) -> bool:
        if self.persistent is None:
            self.persistent = store_is_persistent(self.scenario, self.plugins)
        return self.persistent

    def _runnable(self, executor: str | None, concurrency: int) -> tuple[str, str | None]:
        """The executor, and why it cannot run the scenario (None: it can)."""
        name = executor_name(self.workers, executor, self.address, concurrency)
        if name == "serial":
            return name, None
        inline = sorted(n for n, origin in self.plugins.origins.items() if origin.source == "inline")
        if inline:
            return name, (f"inline plugins ({', '.join(inline)}) cannot reach worker processes; "
                          "install them as packages or use the serial executor")
        if not self._store_persistent():
            return name, str(not_persistent(name, self.scenario))
        return name, None

    def _default_concurrency(self, executor: str | None, suggested: int) -> int:
        """The backend's suggestion where the run can take it (a persistent store, installed
        plugins, not ``--executor serial``), else 1: a default never refuses a run."""
        if suggested <= 1 or executor == "serial":
            return 1
        return suggested if self._runnable(executor, suggested)[1] is None else 1

    def _check_executor(self, executor: str | None) -> str:
        name, problem = self._runnable(executor, self.concurrency)
        if problem is not None:
            raise AblationError(problem)
        return name


def check_resumable(folder: Path, scenario: Scenario, plugins: Plugins) -> None:
    """The run folder to finish recorded ``scenario``, can take its pictures, and its results outlive a run."""
    from ..runs.folder import RunFolder

    RunFolder(folder).check_same(scenario)
    pictures = folder / "trajectories"
    if pictures.exists() and not pictures.is_dir():
        raise AblationError(f"{pictures} is not a folder; move it away so the run can save its pictures there")
    if not store_is_persistent(scenario, plugins):
        raise AblationError(f"state store {scenario.state.use!r} keeps no results across runs: "
                            "resuming needs a persistent store such as sqlite")


def _warm_workers_early(scenario: Scenario, plugins: Plugins, workers: int, executor: str | None,
                        concurrency: int | None) -> None:
    """Start the workers' fork server now, warming it while the checks run, when the run will likely
    use worker processes: ``--workers``/``--concurrency`` above 1, or the backend's options asking
    for trials in flight (the litellm backends' ``concurrency``). A guess only: the process executor
    starts the server itself when none runs."""
    if executor not in (None, "process"):
        return
    wanted = concurrency
    if wanted is None:
        try:
            options = plugins.registry.validate_options("llm_backend", scenario.backend.use, scenario.backend.options)
            wanted = getattr(options, "concurrency", 1)
        except Exception:  # noqa: BLE001 -- check 4 reports a backend that cannot be built
            wanted = 1
    if workers > 1 or executor == "process" or (type(wanted) is int and wanted > 1):
        from .warm_start import start_warm_server

        start_warm_server(scenario.model_dump(mode="json"))


def _spending_cap(scenario: Scenario, plugins: Plugins, max_tokens: int | None,
                  max_cost: float | None) -> "SpendingCap | None":
    """The run's :class:`~.spending.SpendingCap` (None without a token or cost limit), priced by
    the scenario's backend."""
    if max_tokens is None and max_cost is None:
        return None
    from .spending import SpendingCap, backend_price

    return SpendingCap(max_tokens, max_cost, backend_price(scenario, plugins) if max_cost is not None else None)
