"""``sqlite``: a durable state store in one SQLite file, and the ``safeembodai show`` command.

The store keeps every step of every trial (control signals, verdicts, execution results R_i,
the LLM's perception and justification text, token usage) and answers R_{i-1}. One file in WAL
mode, one transaction per step, a versioned schema; several worker processes may write
different trials to the same file at once. See ``docs/state.md``.

This module only registers: ``sqlite3`` and ``rich`` are imported by the implementation
modules, when a store is built or the command runs.
"""

from __future__ import annotations

from pathlib import Path
from typing import Literal

import click
from pydantic import BaseModel, ConfigDict, Field

from safeembodai_core.errors import ComponentError, StateStoreError
from safeembodai_core.hookspecs import hookimpl

from .sqlite_file import DEFAULT_FILE

__all__ = ["DEFAULT_FILE", "SqliteOptions", "StateStoreOpenError", "resolve_path"]


class SqliteOptions(BaseModel):
    """Options of the ``sqlite`` state store."""

    model_config = ConfigDict(extra="forbid")

    path: Path | None = Field(None, description=f"database file (default: <run folder>/{DEFAULT_FILE})")
    timeout_s: float = Field(30.0, gt=0, le=3600, description="how long to wait for another writer's lock")
    synchronous: Literal["normal", "full"] = Field(
        "normal", description="normal: survives process crashes; full: also power loss (slower)")


class StateStoreOpenError(StateStoreError, ComponentError):
    """The store could not be built (no path, unreadable or foreign file); names the file."""


def resolve_path(options: SqliteOptions, run_dir: str | None) -> Path:
    """The database file: ``path`` if set, else ``<run_dir>/results.sqlite``; a clear error if neither."""
    if options.path is not None:
        return Path(options.path).expanduser()
    if run_dir:
        return Path(run_dir) / DEFAULT_FILE
    raise StateStoreOpenError(
        "state store 'sqlite': no 'path' option and no run folder to put "
        f"{DEFAULT_FILE} in; set state.options.path in the scenario"
    )


def _factory(options: SqliteOptions, context):
    from .sqlite_db import SqliteStateStore

    path = resolve_path(options, context.run_dir)
    try:
        return SqliteStateStore(path, timeout_s=options.timeout_s, synchronous=options.synchronous)
    except StateStoreError as error:  # reported as is, not as a plugin bug
        raise StateStoreOpenError(str(error)) from None


@hookimpl
def register_state_stores(register):
    register("sqlite", _factory, options=SqliteOptions,
             description="one SQLite file (WAL): durable steps, safe with parallel workers")


@hookimpl
def register_commands(cli):
    @cli.command("show")
    @click.argument("run", type=click.Path(exists=True))
    @click.option("--trial", "trial", default=None, metavar="N|ID",
                  help="Trial index (with --env/--arm/--condition when several cells have one) or full trial id "
                       "(environment/arm/condition/index); omit to list trials.")
    @click.option("--env", "--environment", "environment", default=None, help="Only trials of this environment label.")
    @click.option("--arm", default=None, help="Only trials of this arm.")
    @click.option("--condition", default=None, help="Only trials of this condition.")
    def show(run, trial, environment, arm, condition):
        """Print the steps of a trial stored in RUN (a .sqlite file or a folder holding results.sqlite):
        prompt summary, the LLM's answer, verdicts and execution, step by step."""
        from .review import show_run

        show_run(run, trial, environment=environment, arm=arm, condition=condition)
