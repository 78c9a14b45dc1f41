"""How a backend, and an environment, describe themselves for the report: :class:`BackendOptions`
and :class:`EnvironmentOptions` (bases for their options models) and what their ``describe``
returns (:class:`BackendDescription`, :class:`EnvironmentDescription`).

Light on purpose (pydantic only): a backend plugin's options module imports it at registration,
which ``safeembodai --help`` runs, and the report reads it without building the backend (no key,
no connection, no heavy import).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from pydantic import BaseModel, ConfigDict


@dataclass(frozen=True)
class BackendDescription:
    """What a report says of a backend before any number (:meth:`BackendOptions.describe`).

    ``model``: the model as the report names it (None: "the backend's own"); ``model_id``: as
    configured, when that differs (a litellm id with its route); ``model_source``: how ``model``
    was read off the configuration; ``simulated``: a banner for a backend that is not an LLM (the
    report, its figures and the trial pictures carry it), with ``why`` (what every number then follows
    from) and ``pilot`` (a legend's few words); ``names_model_in_replies``: the replies
    name the model that answered, and the report prefers those names; ``inputs``: options whose
    values are the inputs behind numbers that look like findings (name, value, what it sets);
    ``weaknesses``: options that shape the other numbers (name, value).
    """

    model: str | None = None
    model_id: str | None = None
    model_source: str | None = None
    simulated: str | None = None
    #: with a banner: what every number follows from (the report says it after the banner), and the
    #: few words figure legends name the pilot by
    why: str | None = None
    pilot: str | None = None
    names_model_in_replies: bool = False
    inputs: tuple[tuple[str, Any, str], ...] = ()
    weaknesses: tuple[tuple[str, Any], ...] = ()


class BackendOptions(BaseModel):
    """A base for a backend's options model: the backend describes itself for the report from its
    options, without being built (no key, no connection, no heavy import). Override :meth:`describe`."""

    model_config = ConfigDict(extra="forbid")

    def describe(self) -> BackendDescription:
        """The report's words on this backend; the default names the ``model`` option when there is one."""
        model = self.model_dump().get("model")
        return BackendDescription(model=str(model) if model else None)


@dataclass(frozen=True)
class EnvironmentDescription:
    """What a report says of an environment beside the step budget (:meth:`EnvironmentOptions.describe`):
    ``time_limit_s``, the simulated time after which a trial ends ``timeout`` whatever its budget;
    ``think_time_s``, the simulated seconds the world runs while the LLM decides, once per step (None:
    the environment has no such clock), or once per call -- every retry too -- when ``think_per_call``."""

    time_limit_s: float | None = None
    think_time_s: float | None = None
    think_per_call: bool = False


class EnvironmentOptions(BaseModel):
    """A base for an environment's options model: the environment describes its clock for the report."""

    model_config = ConfigDict(extra="forbid")

    def describe(self) -> EnvironmentDescription:
        """The report's words on this environment's clock; the default: none."""
        return EnvironmentDescription()
