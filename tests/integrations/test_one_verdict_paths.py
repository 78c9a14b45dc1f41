"""One reply, one verdict on the Gymnasium and Inspect paths too.

The whole replies of ``tests/core/reply_strategies.py`` (chat-completion bodies: choices,
reasoning, finish reasons, duplicate envelope keys, wrappings) are read by
``reply_from_chat_completion`` -- what the litellm backend does with a server's body -- and then:

* the Gymnasium env reads the reply an ``LLMAgent`` hands it (``env.read``, what ``env.step`` does);
* the reply crosses Inspect as ``safeembodai/<backend>`` sends it (``ModelOutput``) and comes back
  as the solver reads it (``backend_reply``), then the loop's reading.

Each must give ``Guard.check_reply``'s verdict -- which ``tests/core/test_one_verdict.py`` holds
equal to the trial loop's and to the contract's -- and accept exactly the same commands.
"""

from __future__ import annotations

import asyncio
import sys
from pathlib import Path

import pytest
from hypothesis import HealthCheck, given, settings

from safeembodai_core import Guard
from safeembodai_core.models import ResponseParseError, read_reply
from safeembodai_core.models.chat_completion import reply_from_chat_completion
from safeembodai_core.plugins import load_plugins

sys.path.insert(0, str(Path(__file__).parents[1] / "core"))
from reply_strategies import bodies  # noqa: E402

PLUGINS = load_plugins(environ={})
SETTINGS = settings(max_examples=120, deadline=None, suppress_health_check=[HealthCheck.too_slow,
                                                                             HealthCheck.function_scoped_fixture])


def guard_verdict(reply):
    report = Guard(rules=[], plugins=PLUGINS).check_reply(reply)
    return ([s.model_dump() for s in report.signals] if report.valid else None), report.reasons


@pytest.fixture(scope="module")
def text_env():
    gymnasium = pytest.importorskip("gymnasium", reason='needs the gym extra: pip install -e ".[gym]"')
    import safeembodai_core.gym  # noqa: F401  (registers the ids)

    env = gymnasium.make("safeembodai/flatland-v0", action_format="text")
    env.reset(seed=0)
    yield env.unwrapped
    env.close()


@SETTINGS
@given(generated=bodies())
def test_the_gymnasium_env_gives_the_guards_verdict(text_env, generated):
    body, plan = generated
    reply = reply_from_chat_completion(body)
    signals, _, reason = text_env.read(reply)
    expected, reasons = guard_verdict(reply)
    assert (signals is not None) == (expected is not None) == (plan is not None)
    if signals is None:
        assert text_env._refusal(reason) == reasons  # what info["reasons"] says, word for word
    else:
        assert [s.model_dump() for s in signals] == expected


class _Fixed:
    def __init__(self, reply) -> None:
        self.reply = reply

    def complete(self, prompt, rng):
        return self.reply

    def close(self) -> None:
        pass


@pytest.fixture(scope="module")
def inspect_model():
    pytest.importorskip("inspect_ai", reason='needs the inspect extra: pip install -e ".[inspect]"')
    from inspect_ai.model import get_model

    return get_model("safeembodai/scripted", responses=["unused"], memoize=False)


@SETTINGS
@given(generated=bodies())
def test_the_inspect_round_trip_gives_the_guards_verdict(inspect_model, generated):
    from inspect_ai.model import GenerateConfig

    from safeembodai_core.integrations.inspect import prompt_messages
    from safeembodai_core.integrations.inspect.bridge import backend_reply
    from safeembodai_core.models import Prompt, TextPart
    from safeembodai_core.seeds import rng

    body, plan = generated
    reply = reply_from_chat_completion(body)
    inspect_model.api.backend = _Fixed(reply)
    messages = prompt_messages(Prompt(system="S", user=(TextPart("instruction", "go"),)), rng(1, "backend"))
    output = asyncio.run(inspect_model.api.generate(messages, [], "none", GenerateConfig()))
    back = backend_reply(output, 0.0)
    expected, reasons = guard_verdict(reply)
    try:
        signals = [s.model_dump() for s in read_reply(back).control]
    except ResponseParseError as error:
        signals = None
        assert reasons == [str(error)]  # refused in the same words as by Guard (and the loop)
    assert signals == expected
    assert (signals is not None) == (plan is not None)
