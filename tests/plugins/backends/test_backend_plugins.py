"""The backend plugins stay light: litellm is imported only by the components that need it."""

from __future__ import annotations

import subprocess
import sys
import textwrap

import pytest


def _run(code: str) -> str:
    done = subprocess.run([sys.executable, "-c", textwrap.dedent(code)], capture_output=True, text=True, timeout=120)
    assert done.returncode == 0, done.stderr[-2000:]
    return done.stdout.strip()


@pytest.mark.slow
def test_registering_and_running_the_mock_with_estimated_tokens_never_imports_litellm():
    out = _run("""
        import sys
        import numpy as np
        from safeembodai_core.plugin.manager import load_plugins
        from safeembodai_core.models import Prompt, TextPart
        plugins = load_plugins(environ={})
        names = plugins.registry.names("llm_backend")
        mock = plugins.registry.build("llm_backend", "mock", {"token_counting": "estimate"})
        reply = mock.complete(Prompt(system="S", user=(TextPart("user", "Human Instruction: \\"go\\""),)),
                              np.random.default_rng(0))
        print(",".join(names), "litellm" in sys.modules, "openai" in sys.modules, reply.usage.prompt_tokens > 0)
    """)
    assert out == "gpt-4o,litellm,local,mock,outside,scripted False False True"


@pytest.mark.slow
def test_building_a_litellm_backend_imports_it_configured_for_offline_use():
    out = _run("""
        import os, sys, logging
        os.environ["K"] = "sk-x"
        from safeembodai_core.plugin.manager import load_plugins
        plugins = load_plugins(environ={})
        assert "litellm" not in sys.modules
        plugins.registry.build("llm_backend", "gpt-4o", {"api_key_env": "K"})
        import litellm
        print(os.environ["LITELLM_LOCAL_MODEL_COST_MAP"], os.environ["LITELLM_MODE"], litellm.suppress_debug_info,
              logging.getLogger("LiteLLM").level == logging.ERROR)
    """)
    assert out == "True PRODUCTION True True"
