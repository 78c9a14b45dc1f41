"""Which of Inspect's model providers the solver runs a trial with, and why not the others.

The loop executes only a reply that the one strict reading takes (:func:`~safeembodai_core.models.read_reply`
after :func:`~safeembodai_core.models.chat_completion.reply_from_chat_completion` for a server's body): a
duplicate key in the envelope, a BOM, ``native_finish_reason``, string indices, an unusual
finish reason are refused there. Inspect's own providers (``openai/``, ``openai-api/``,
``anthropic/``, ...) parse the server's body themselves and hand over a ``ModelOutput``, from which
none of that can be seen: the same reply would get another verdict under Inspect than under
``safeembodai ablate``, ``Guard`` or Gymnasium. So a task runs only on a provider that hands the
solver the whole reply (ours, because the project's rule is one verdict per reply; the paper has no
Inspect path):

* ``safeembodai/<backend>``: a registered backend reads the server's raw body itself (the
  ``litellm`` backend reaches every model litellm does: ``--model safeembodai/litellm/openai/gpt-4o``);
* ``mockllm/``: Inspect's test provider; its outputs are built in memory, there is no body to misread.

Any other provider is refused before the first sample, with the flags that switch to ours.
"""

from __future__ import annotations

from typing import Any

from ...errors import SafeEmbodAIError
from ...trust.text import terminal_text

#: The providers whose replies reach the solver whole (see the module docstring).
WHOLE_REPLY_PROVIDERS = ("safeembodai", "mockllm")

try:  # Inspect prints this error's message alone (no traceback) and exits 1
    from inspect_ai._util.error import PrerequisiteError as _Refusal
except ImportError:  # a later Inspect that moved it: a plain error, with the same message
    _Refusal = RuntimeError  # type: ignore[assignment,misc]


class ProviderRefused(_Refusal, SafeEmbodAIError):
    """A task was asked to run on a provider that cannot show the solver the whole reply."""

    def __init__(self, message: str) -> None:
        Exception.__init__(self, message)
        from rich.markup import escape

        self.message = escape(message)  # what Inspect prints (rich): as written, never read as markup


def provider_name(model: Any) -> tuple[str, str]:
    """``(provider, model name)`` of an Inspect model or model string (``("openai-api", "fake/robot-pilot")``);
    ``("", ...)`` for what names no provider (refused)."""
    from inspect_ai.model import ModelName

    try:
        name = ModelName(model)
    except Exception:  # not "provider/name": no provider, so none that shows the whole reply
        return "", str(model)[:200]
    return str(name.api), str(name.name)


def switch_flags(provider: str, name: str) -> str:
    """The ``--model``/``-M`` flags that run the same model through ``safeembodai/litellm``."""
    if provider == "openai-api":  # Inspect's generic OpenAI-compatible service: <SERVICE>_BASE_URL, _API_KEY
        service, _, model = name.partition("/")
        env = service.upper().replace("-", "_")
        return (f"--model safeembodai/litellm/openai/{model or service} -M api_base=${env}_BASE_URL "
                f"-M api_key_env={env}_API_KEY")
    if provider == "openai":
        return f"--model safeembodai/litellm/{name}"
    key = f"{provider.upper().replace('-', '_')}_API_KEY"
    return f"--model safeembodai/litellm/{provider}/{name} -M api_key_env={key}"


def check_provider(model: Any) -> None:
    """Raise :class:`ProviderRefused` unless ``model``'s provider hands over the whole reply."""
    provider, name = provider_name(model)
    if provider in WHOLE_REPLY_PROVIDERS:
        return
    provider, name = terminal_text(provider)[:100], terminal_text(name)[:200]  # shown: never an escape sequence
    raise ProviderRefused(
        f"safeembodai: Inspect's {provider!r} provider parses the server's reply itself, so what SafeEmbodAI's "
        f"strict reading refuses (duplicate keys, a BOM, string indices, an unusual finish reason) cannot be seen "
        f"and a reply would get another verdict here than under `safeembodai ablate`. Run the same model through "
        f"SafeEmbodAI's provider, which reads the raw reply: {switch_flags(provider, name)} (docs/inspect.md, "
        f"\"Which providers\")")


def check_active_model() -> None:
    """:func:`check_provider` on Inspect's active model when there is one (``inspect eval`` sets it
    before it builds the task); nothing when none is set yet (the solver checks again). Never the
    default model of ``INSPECT_EVAL_MODEL``: a task built for another model must not be refused by it,
    nor build a provider only to check it."""
    try:
        from inspect_ai.model._model import active_model
    except ImportError:  # a later Inspect that moved it: the solver's check is the one that counts
        return
    model = active_model()
    if model is not None:
        check_provider(model)
