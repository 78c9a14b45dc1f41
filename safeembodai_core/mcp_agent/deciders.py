"""The two deciders an ablation can run, built from the scenario's components.

* ``pilot`` (the default): the scenario's backend answers the paper's prompt and its plans become
  motion calls (:class:`~.pilot.PilotDecider`); with the default backend, ``mock``, that is the
  offline simulated pilot, no key and no network.
* ``tool-calls``: a litellm model calls the MCP tools itself (:class:`~.tool_agent.ToolCallingDecider`);
  the scenario's backend must be a litellm one (``gpt-4o``, ``litellm``, ``local``): its ``model``,
  ``api_base``, ``api_key_env``, ``temperature``, ``max_tokens`` and ``timeout_s`` are used.
"""

from __future__ import annotations

from typing import Callable

from ..plugin.building import ComponentBuilder
from ..errors import SafeEmbodAIError
from ..models import TrialSpec
from ..plugin.manager import Plugins
from ..scenario import Scenario
from .loop import Decider

DECIDERS = ("pilot", "tool-calls")
#: What the ``tool-calls`` decider reads of a backend's options.
MODEL_OPTIONS = ("model", "timeout_s", "max_tokens")


def pilot(scenario: Scenario, plugins: Plugins) -> Callable[[TrialSpec], Decider]:
    from .pilot import PilotDecider

    builder = ComponentBuilder(scenario, plugins)

    def make(spec: TrialSpec) -> Decider:
        return PilotDecider(builder.backend(spec.seed), builder.build("perception", scenario.perception, spec.seed),
                            builder.build("prompt_builder", scenario.prompt_builder, spec.seed))

    return make


def tool_calls(scenario: Scenario, plugins: Plugins) -> Callable[[TrialSpec], Decider]:
    from .tool_agent import ToolCallingDecider

    ref = scenario.backend
    options = plugins.registry.get("llm_backend", ref.use).options
    if not all(name in options.model_fields for name in MODEL_OPTIONS):
        raise SafeEmbodAIError(f"--decider tool-calls needs a litellm backend (gpt-4o, litellm, local), not "
                               f"{ref.use!r}: it reads the model, its server and key from the backend's options")
    read = plugins.registry.validate_options("llm_backend", ref.use, ref.options)
    return lambda spec: ToolCallingDecider(read)


def decider_factory(name: str, scenario: Scenario, plugins: Plugins) -> Callable[[TrialSpec], Decider]:
    """The factory of decider ``name`` (module docstring): one decider per trial."""
    if name == "pilot":
        return pilot(scenario, plugins)
    if name == "tool-calls":
        return tool_calls(scenario, plugins)
    raise SafeEmbodAIError(f"unknown decider {name!r}: use {' or '.join(DECIDERS)}")
