"""SafeEmbodAI in Inspect AI (the ``inspect`` extra): tasks, solver, scorers and a model provider.

``inspect eval safeembodai/mo --model safeembodai/litellm/gpt-4o`` runs a scenario's ablation
through Inspect (only on a provider that shows the whole reply: :mod:`.providers`); ``--model
safeembodai/mock`` with the offline simulated pilot. The names are registered by
the top-level module ``safeembodai`` (Inspect names a package's tasks after the module that
defines them; ``docs/inspect.md``). Importing this package needs ``inspect-ai`` installed.
"""

from .bridge import InspectBackend, prompt_from_messages, prompt_messages
from .provider import SafeEmbodAIModelAPI
from .scorers import catalog_metric, catalog_scorers
from .solver import RESULT_KEY, trial_solver
from .task import SHIPPED, scenario_path, scenario_task

__all__ = [
    "InspectBackend", "RESULT_KEY", "SHIPPED", "SafeEmbodAIModelAPI", "catalog_metric", "catalog_scorers",
    "prompt_from_messages", "prompt_messages", "scenario_path", "scenario_task",
    "trial_solver",
]
