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
