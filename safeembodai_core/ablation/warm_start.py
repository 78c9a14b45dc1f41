"""Worker processes that start warm: forked from a server that has already imported what they need.

A spawned worker starts a fresh interpreter and imports the core, the plugins and what the
scenario's backend needs (litellm alone takes about 5 s of CPU) before its first call, after the
coordinator has done the same for its own checks: on 2 cores the first call of a GPT-4o ablation
left 14.5 s after the start. Where the platform has it (Linux, macOS), workers are instead forked
from multiprocessing's *fork server*, started by :func:`start_warm_server` before the coordinator's
own checks, so both warm up at once on two cores. The server imports this module, which then loads
the plugins and builds (and closes) the scenario's backend once -- what the coordinator's preflight
does too -- so every module that takes is already imported in each worker, shared copy-on-write,
once for all workers. A warm-up that fails only costs the time: the worker builds everything itself
and reports what fails, as before. Elsewhere (Windows) workers are spawned as before.

A forked worker takes the coordinator's environment variables as they are when it starts (the
server's are a snapshot of an earlier moment) and knows its coordinator by a pipe, not by its
parent (the server is): see :mod:`.lifeline`.
"""

from __future__ import annotations

import json
import multiprocessing
import os
from typing import Any

#: Set only in the fork server's environment, for the warm-up: the scenario (JSON).
WARM_SCENARIO = "SAFEEMBODAI_WARM_SCENARIO"
#: A scenario longer than this is not passed through the environment (the warm-up then only imports).
MAX_SCENARIO_CHARS = 64_000


def can_fork_workers() -> bool:
    """Whether workers can start from a fork server on this platform."""
    return "forkserver" in multiprocessing.get_all_start_methods()


def worker_context() -> Any:
    """The multiprocessing context workers start from: the fork server where there is one, else spawn."""
    return multiprocessing.get_context("forkserver" if can_fork_workers() else "spawn")


def start_warm_server(scenario_json: dict[str, Any] | None) -> bool:
    """Start the fork server now, warming it for ``scenario_json`` (in the background: this returns
    at once). Does nothing where there is no fork server, or when one already runs (it stays as it
    was warmed). Returns whether workers will fork from a server."""
    if not can_fork_workers():
        return False
    from multiprocessing import forkserver

    context = multiprocessing.get_context("forkserver")
    context.set_forkserver_preload([__name__])
    text = json.dumps(scenario_json) if scenario_json is not None else ""
    previous = os.environ.get(WARM_SCENARIO)
    if text and len(text) <= MAX_SCENARIO_CHARS:
        os.environ[WARM_SCENARIO] = text  # the server is started with this environment
    try:
        forkserver.ensure_running()
    finally:
        if previous is None:
            os.environ.pop(WARM_SCENARIO, None)
        else:
            os.environ[WARM_SCENARIO] = previous
    return True


def _warm_up(text: str) -> None:
    """In the fork server: import what a worker will need by doing what it will do first."""
    from ..plugin.manager import load_plugins
    from ..plugin.building import ComponentBuilder
    from ..scenario import Scenario

    plugins = load_plugins()
    if not text:
        return
    scenario = Scenario.model_validate(json.loads(text))
    backend = ComponentBuilder(scenario, plugins).backend()
    backend.close()


def _in_fork_server() -> None:
    text = os.environ.pop(WARM_SCENARIO, None)
    if text is None:  # imported anywhere else: nothing to do
        return
    try:
        _warm_up(text)
    except Exception:  # noqa: BLE001 -- the worker builds everything again and reports what fails
        pass


_in_fork_server()
