"""One reply, one verdict: the trial loop and the library guard read a whole reply the same way.

Whole replies (chat-completion bodies: choices, reasoning, finish reasons, duplicate envelope keys,
wrappings; ``reply_strategies``) are read by :func:`reply_from_chat_completion`, then handed to the
trial loop (through a backend, as ``run`` and ``ablate`` do) and to ``Guard.check_reply``. Both must
give the verdict the contract gives -- known from how the body was made -- and the same reasons,
and the loop must run exactly the plan the guard accepted. The Gymnasium and Inspect paths are held
to the same in ``tests/integrations/test_one_verdict_paths.py``; the HTTP transport gives the same
reply as this reader in ``tests/backends/test_reply_transport.py``.
"""

from __future__ import annotations

import pytest
import sys
from pathlib import Path

from hypothesis import HealthCheck, given, settings

from safeembodai_core import Guard, run_guarded_trial
from safeembodai_core.components import LLMBackend
from safeembodai_core.loop import Defences
from safeembodai_core.models.chat_completion import reply_from_chat_completion
from safeembodai_core.plugins import load_plugins
from safeembodai_core.testing import CorridorWorld

sys.path.insert(0, str(Path(__file__).parent))
from reply_strategies import bodies  # noqa: E402

PLUGINS = load_plugins(environ={})
READ_ONLY = Defences(failure_threshold=0, on_exhausted="hold")  # one attempt, the reading alone decides


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


# What a hostile read of the first version found (issue 20's review) ------------------------------

def _body(message: dict, **choice) -> str:
    import json

    return json.dumps({"choices": [{"index": 0, "message": {"role": "assistant", **message}, **choice}]})


def _verdict(body) -> list[str]:
    return Guard(rules=[], plugins=PLUGINS).check_reply(reply_from_chat_completion(body)).reasons


def test_a_relays_native_finish_reason_that_is_not_a_normal_end_is_the_reason():
    from safeembodai_core.testing import answer, turn

    good = answer(turn(30))
    for native, reason in (("length", "stop"), ("error", "stop"), ("MAX_TOKENS", None), ("length", None)):
        fields = {"native_finish_reason": native, **({"finish_reason": reason} if reason else {})}
        [why] = _verdict(_body({"content": good}, **fields))
        assert f'finish reason "{native}"' in why
    assert _verdict(_body({"content": good}, finish_reason="stop", native_finish_reason="end_turn")) == []


def test_a_closing_tag_quoted_inside_the_answer_is_not_a_reasoning_boundary():
    import json

    from safeembodai_core.testing import answer, straight, turn

    data = json.loads(answer(turn(30)))
    data["perception"][0]["result"] = 'The instruction contains "</think> drive straight 390"'
    assert _verdict(_body({"content": json.dumps(data)}, finish_reason="stop")) == []
    hidden = f"Considering {answer(straight(390))}.</think>\n{answer(turn(30))}"
    assert "other than the answer" in _verdict(_body({"content": hidden}, finish_reason="stop"))[0]


def test_every_reasoning_field_is_read_for_a_second_plan():
    from safeembodai_core.testing import answer, straight, turn

    good, other = answer(turn(30)), answer(straight(390))
    for message in ({"thinking": other}, {"reasoning": other},
                    {"reasoning_details": [{"type": "reasoning.text", "text": other}]},
                    {"thinking_blocks": [{"type": "thinking", "thinking": other}]}):
        [why] = _verdict(_body({"content": good, **message}, finish_reason="stop"))
        assert "other than the answer" in why, message
    assert _verdict(_body({"content": good, "thinking_blocks": [{"thinking": "fine"}]}, finish_reason="stop")) == []


def test_an_error_beside_choices_invalid_utf8_and_a_lone_surrogate_anywhere_refuse_the_reply():
    import json

    from safeembodai_core.testing import answer, turn

    good = json.loads(_body({"content": answer(turn(30))}, finish_reason="stop"))
    with_error = json.dumps({**good, "error": {"message": "oops"}})
    assert "error object" in _verdict(with_error)[0]
    invalid = json.dumps(good).encode().replace(b'"stop"', b'"st\xffop"')  # a byte that is no UTF-8, in a string
    assert "not valid UTF-8" in _verdict(invalid)[0]
    assert "lone surrogate" in _verdict(json.dumps({**good, "id": "x"}).replace('"x"', '"\\ud800"'))[0]
