"""A backend's optional capabilities are declared methods: an object with only ``complete`` gets
``LLMBackend``'s defaults for the rest (the core calls them, never ``getattr``); one without
``complete`` is refused, naming the plugin that built it."""

from __future__ import annotations

import numpy as np
import pytest

from safeembodai_core.contracts.components import BackendReply, LLMBackend, as_llm_backend
from safeembodai_core.errors import PluginError
from safeembodai_core.hookspecs import hookimpl
from safeembodai_core.models import DEFAULT_LIMITS, Prompt
from safeembodai_core.testing import answer, inline_plugins, run_tiny_trial, turn


class OnlyComplete:
    def complete(self, prompt, rng):
        return BackendReply(text=answer(turn(10)))


class Priced(OnlyComplete):
    concurrency = 4

    def cost(self, prompt_tokens, completion_tokens):
        return 0.5


def test_a_duck_backend_gets_the_declared_defaults_and_keeps_its_own():
    plain = as_llm_backend(OnlyComplete())
    assert isinstance(plain, LLMBackend) and plain.concurrency == 1
    assert plain.cost(10, 10) is None and plain.cache_request(Prompt(system="", user=())) is None
    assert plain.prepare_attempt(index=0, limits=DEFAULT_LIMITS, rng=np.random.default_rng(0)) is None
    plain.preflight()
    plain.close()
    priced = as_llm_backend(Priced())
    assert priced.cost(10, 10) == 0.5 and priced.concurrency == 4
    native = OnlyComplete.__new__(type("Native", (LLMBackend,), {"complete": OnlyComplete.complete}))
    assert as_llm_backend(native) is native
    with pytest.raises(TypeError, match="complete"):
        as_llm_backend(object())


class _Registering:
    @hookimpl
    def register_llm_backends(self, register):
        register("duck", lambda options, context: Priced())
        register("nothing", lambda options, context: object())


def test_the_registry_declares_them_and_names_the_plugin_of_an_object_that_is_no_backend():
    plugins = inline_plugins(("ducks", _Registering()))
    built = plugins.registry.build("llm_backend", "duck", {})
    assert isinstance(built, LLMBackend) and built.cost(1, 1) == 0.5
    with pytest.raises(PluginError, match="'ducks'.*needs a complete"):
        plugins.registry.build("llm_backend", "nothing", {})
    result, _ = run_tiny_trial(plugins=[("ducks", _Registering())], backend={"use": "duck"}, max_steps=1)
    assert result.cost_usd == 0.5  # the trial priced itself through the declared method
