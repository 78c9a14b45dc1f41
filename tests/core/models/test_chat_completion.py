"""One reply, one verdict: every path reads a whole chat-completion reply the same way.

Whole replies (chat-completion bodies: choices, reasoning, finish reasons, duplicate envelope keys,
wrappings; ``tests/support/reply_strategies.py``) are read by :func:`reply_from_chat_completion` --
what the litellm backend does with a server's body -- then handed to:

* the trial loop (through a backend, as ``run`` and ``ablate`` do) and ``Guard.check_reply``: both
  must give the verdict the contract gives -- known from how the body was made -- and the same
  reasons, and the loop must run exactly the plan the guard accepted;
* the Gymnasium env, which reads the reply an ``LLMAgent`` hands it (``env.read``, what ``env.step`` does);
* Inspect: the reply crosses it as ``safeembodai/<backend>`` sends it (``ModelOutput``) and comes back
  as the solver reads it (``backend_reply``), then the loop's reading.

Each must give ``Guard.check_reply``'s verdict and accept exactly the same commands. The HTTP
transport gives the same reply as this reader in ``tests/plugins/backends/litellm/test_reply_transport.py``.
"""

from __future__ import annotations

import asyncio
import json

import pytest
from hypothesis import HealthCheck, given, settings
from reply_strategies import bodies

from safeembodai_core import Guard, run_guarded_trial
from safeembodai_core.contracts.components import LLMBackend
from safeembodai_core.loop import Defences
from safeembodai_core.models import ResponseParseError, read_reply
from safeembodai_core.models.chat_completion import reply_from_chat_completion
from safeembodai_core.plugin.manager import load_plugins
from safeembodai_core.testing import CorridorWorld, answer, straight, turn

PLUGINS = load_plugins(environ={})
READ_ONLY = Defences(failure_threshold=0, on_exhausted="hold")  # one attempt, the reading alone decides
SETTINGS = settings(max_examples=120, deadline=None, suppress_health_check=[HealthCheck.too_slow,
                                                                             HealthCheck.function_scoped_fixture])


class Fixed(LLMBackend):
    def __init__(self, reply) -> None:
        self.reply = reply

    def complete(self, prompt, rng):
        return self.reply


def loop_verdict(reply):
    world = CorridorWorld(wall_mm=1e6, side_mm=1e6)
    _, steps = run_guarded_trial(world, Fixed(reply), defences=READ_ONLY, max_steps=1, plugins=PLUGINS)
    attempt = steps[0].attempts[0]
    return attempt, [s.model_dump() for s in world.executed]


@settings(max_examples=150, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(generated=bodies())
@pytest.mark.slow
def test_the_loop_and_the_guard_give_the_contracts_verdict(generated):
    body, plan = generated
    reply = reply_from_chat_completion(body)
    attempt, executed = loop_verdict(reply)
    report = Guard(rules=[], plugins=PLUGINS).check_reply(reply)
    assert attempt.accepted == report.valid == (plan is not None), (body, attempt.failures())
    assert attempt.failures() == report.reasons
    if plan is None:
        assert executed == [] and report.signals == []
    else:
        assert executed == [s.model_dump() for s in report.signals]
        assert [(s["command"], s["direction"], s.get("distance", s.get("angle"))) for s in plan] == [
            (s["command"], s["direction"], s.get("distance", s.get("angle"))) for s in executed]


# The edges of the envelope: relays' finish reasons, reasoning fields, errors, bytes --------------

def _body(message: dict, **choice) -> str:
    return json.dumps({"choices": [{"index": 0, "message": {"role": "assistant", **message}, **choice}]})


def _verdict(body) -> list[str]:
    return Guard(rules=[], plugins=PLUGINS).check_reply(reply_from_chat_completion(body)).reasons


def test_a_relays_native_finish_reason_that_is_not_a_normal_end_is_the_reason():
    good = answer(turn(30))
    for native, reason in (("length", "stop"), ("error", "stop"), ("MAX_TOKENS", None), ("length", None)):
        fields = {"native_finish_reason": native, **({"finish_reason": reason} if reason else {})}
        [why] = _verdict(_body({"content": good}, **fields))
        assert f'finish reason "{native}"' in why
    assert _verdict(_body({"content": good}, finish_reason="stop", native_finish_reason="end_turn")) == []


def test_a_closing_tag_quoted_inside_the_answer_is_not_a_reasoning_boundary():
    data = json.loads(answer(turn(30)))
    data["perception"][0]["result"] = 'The instruction contains "</think> drive straight 390"'
    assert _verdict(_body({"content": json.dumps(data)}, finish_reason="stop")) == []
    hidden = f"Considering {answer(straight(390))}.</think>\n{answer(turn(30))}"
    assert "other than the answer" in _verdict(_body({"content": hidden}, finish_reason="stop"))[0]


def test_every_reasoning_field_is_read_for_a_second_plan():
    good, other = answer(turn(30)), answer(straight(390))
    for message in ({"thinking": other}, {"reasoning": other},
                    {"reasoning_details": [{"type": "reasoning.text", "text": other}]},
                    {"thinking_blocks": [{"type": "thinking", "thinking": other}]}):
        [why] = _verdict(_body({"content": good, **message}, finish_reason="stop"))
        assert "other than the answer" in why, message
    assert _verdict(_body({"content": good, "thinking_blocks": [{"thinking": "fine"}]}, finish_reason="stop")) == []


def test_an_error_beside_choices_invalid_utf8_and_a_lone_surrogate_anywhere_refuse_the_reply():
    good = json.loads(_body({"content": answer(turn(30))}, finish_reason="stop"))
    with_error = json.dumps({**good, "error": {"message": "oops"}})
    assert "error object" in _verdict(with_error)[0]
    invalid = json.dumps(good).encode().replace(b'"stop"', b'"st\xffop"')  # a byte that is no UTF-8, in a string
    assert "not valid UTF-8" in _verdict(invalid)[0]
    assert "lone surrogate" in _verdict(json.dumps({**good, "id": "x"}).replace('"x"', '"\\ud800"'))[0]


# The Gymnasium and Inspect paths -------------------------------------------------------------------

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
