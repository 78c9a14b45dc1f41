"""The litellm backend's strict raw reading, through its real transport against the fake server.

The reply is read from the body the server sent (not litellm's parsed object): a ``<think>`` block
stays in the text, every choice is counted, duplicate keys refuse the reply, the finish reason
reaches the core as sent (test_litellm_hostile.py); a redirect is never followed, and an HTTP 200
carrying only an error object is the provider's error (retried). See docs/backend_calls.md, "What
the backend reads from the server".
"""

from __future__ import annotations

import json

import numpy as np
import pytest

from backend_helpers import one_trial_steps
from fake_openai import DROP, Envelope, FakeOpenAI, Raw, Redirect, Reply, Status, choice
from safeembodai_core.errors import BackendError, ComponentError
from safeembodai_core.models import Prompt, TextPart, read_reply
from safeembodai_core.models.strict_json import ResponseParseError
from safeembodai_core.testing import answer, straight, turn

GOOD = answer(turn(30))
OTHER = answer(straight(390))  # a second plan, driving straight on


def _prompt() -> Prompt:
    return Prompt(system="Role: robot. JSON", user=(TextPart("user", 'Human Instruction: "go"'),))


def _backend(plugins, server, name="gpt-4o", **options):
    base = {"api_base": server.url, "backoff_s": 0.0, "backoff_max_s": 0.0, "timeout_s": 5.0, "max_retries": 0}
    if name != "local":
        base["api_key_env"] = "SAFEEMBODAI_TEST_KEY"
    return plugins.registry.build("llm_backend", name, {**base, **options})


def _complete(plugins, server, **options):
    return _backend(plugins, server, **options).complete(_prompt(), np.random.default_rng(0))


def _origin(server) -> str:
    return server.url.rsplit("/", 1)[0]  # http://127.0.0.1:PORT


def _refused(reply, match: str) -> None:
    with pytest.raises(ResponseParseError, match=match):
        read_reply(reply)


# (a) a second plan in a leading <think> block ---------------------------------------------------

def test_a_think_block_stays_in_the_text_and_a_second_plan_in_it_is_refused(built_plugins, fake_server, fake_key):
    content = f"<think>Maybe {OTHER} but no.</think>\n{GOOD}"
    fake_server.default = Reply(content)
    reply = _complete(built_plugins, fake_server)
    assert reply.text == content and reply.reasoning is None  # litellm would have moved the block away
    assert reply.origin == _origin(fake_server) and reply.choices == 1
    _refused(reply, "reasoning holds a JSON object other than the answer")
    fake_server.default = Reply(f"<think>Draft: {GOOD}</think>\n{GOOD}")  # the same plan: one plan
    assert read_reply(_complete(built_plugins, fake_server)).control[0].angle == 30


def test_local_reads_the_raw_body_too(built_plugins, fake_server):
    content = f"<think>{OTHER}</think>{GOOD}"
    fake_server.default = Reply(content)
    reply = _complete(built_plugins, fake_server, name="local")
    assert reply.text == content and reply.origin == _origin(fake_server) and reply.model == "local"
    _refused(reply, "other than the answer")


# (b) redirects are errors, never followed ------------------------------------------------------

@pytest.mark.parametrize("code", [307, 302, 301, 303, 308])
def test_a_redirect_to_another_server_is_an_error_and_never_followed(built_plugins, fake_server, fake_key, code):
    with FakeOpenAI(Reply(OTHER)) as elsewhere:
        fake_server.default = Redirect(code, elsewhere.url + "/chat/completions")
        with pytest.raises(BackendError) as raised:
            _complete(built_plugins, fake_server, max_retries=3)
        assert elsewhere.requests == []  # neither re-POSTed (307) nor fetched (302)
    message = str(raised.value)
    assert f"gave up after 1 try: redirected (HTTP {code}), not followed" in message
    assert f"Location {_origin(elsewhere)}" in message and "/chat/completions" not in message
    assert len(fake_server.requests) == 1 and fake_key not in message


def test_a_redirect_to_the_same_server_is_not_followed_either(built_plugins, fake_server, fake_key):
    fake_server.push(Redirect(307, "/v1/other/chat/completions?token=secret-in-query"))
    with pytest.raises(BackendError, match=r"redirected \(HTTP 307\)") as raised:
        _complete(built_plugins, fake_server, max_retries=2)
    assert len(fake_server.requests) == 1 and "secret-in-query" not in str(raised.value)
    assert f"Location {_origin(fake_server)}" in str(raised.value)


# (c) the whole envelope, read strictly ---------------------------------------------------------

@pytest.mark.parametrize("choices", [[choice(GOOD), choice(OTHER, index=1)], [choice(OTHER, index=1), choice(GOOD)]],
                         ids=["in-order", "reversed"])
def test_two_choices_are_refused_and_both_plans_stay_on_record(built_plugins, fake_server, fake_key, choices):
    fake_server.default = Envelope(choices)
    reply = _complete(built_plugins, fake_server)
    assert reply.choices == 2
    assert json.loads(reply.text)["choices"] == choices  # the whole body, both plans
    _refused(reply, "2 choices")


def test_a_lone_choice_that_is_not_index_0_is_refused(built_plugins, fake_server, fake_key):
    fake_server.default = Envelope([choice(GOOD, index=1)])
    _refused(_complete(built_plugins, fake_server), 'index "1", not 0')


def _body(message: str, tail: str = '"finish_reason": "stop"') -> str:
    return ('{"id": "x", "object": "chat.completion", "created": 0, "model": "gpt-4o", "choices": [{"index": 0, '
            f'"message": {message}, {tail}}}], "usage": {{"prompt_tokens": 3, "completion_tokens": 4}}}}')


@pytest.mark.parametrize("body,seen", [
    (_body('{"role": "assistant", "content": %s, "content": %s}' % (json.dumps(OTHER), json.dumps(GOOD))), "content"),
    (_body('{"role": "assistant", "content": %s}' % json.dumps(GOOD),
           '"finish_reason": "length", "finish_reason": "stop"'), "finish_reason"),
], ids=["two-contents", "two-finish-reasons"])
def test_duplicate_keys_in_the_envelope_refuse_the_reply_and_the_record_keeps_the_body(
        built_plugins, fake_server, fake_key, body, seen):
    fake_server.default = Raw(body)
    reply = _complete(built_plugins, fake_server)
    assert reply.envelope_error and seen in reply.envelope_error and reply.text == body
    _refused(reply, "refused as a whole")


def test_a_refused_envelope_is_recorded_with_its_body_and_origin_in_a_trial(built_plugins, fake_server, fake_key):

    twice = _body('{"role": "assistant", "content": %s, "content": %s}' % (json.dumps(OTHER), json.dumps(GOOD)))
    fake_server.push(Raw(twice))
    fake_server.default = Reply(GOOD)
    data = {"name": "raw", "trials": 1, "max_steps": 1, "seed": 3, "environments": ["flatland"], "state": "memory",
            "backend": {"use": "gpt-4o", "options": {"api_base": fake_server.url, "api_key_env": "SAFEEMBODAI_TEST_KEY",
                                                      "backoff_s": 0.0, "timeout_s": 5.0}},
            "arms": {"safe": {"security_prefix": True, "safety_validation": True}}, "conditions": {"no_attack": {}}}
    [step] = one_trial_steps(built_plugins, data, "safe")
    first, second = step.attempts
    assert "refused as a whole" in first.parse_error and "content" in first.parse_error
    assert first.raw_text == twice and first.origin == _origin(fake_server)
    assert second.accepted and [e.signal.describe() for e in step.executed] == ["turn left 30 deg"]


# (d) finish reasons reach the core as sent: in test_litellm_hostile.py

# (e) an HTTP 200 that carries only an error object ---------------------------------------------

def test_an_error_object_in_a_200_is_the_providers_error_retried_like_a_5xx(built_plugins, fake_server, fake_key):
    error = {"error": {"message": f"Model overloaded \x1b[31mtry later\x1b[0m (key {fake_key})",
                       "type": "server_error"}}
    fake_server.default = Raw(json.dumps(error))
    with pytest.raises(BackendError) as raised:
        _complete(built_plugins, fake_server, max_retries=1)
    message = str(raised.value)
    assert len(fake_server.requests) == 2
    assert "gave up after 2 tries: provider error in an HTTP 200 reply" in message
    assert "Model overloaded" in message and "try later" in message and "(no message)" not in message
    assert "\x1b" not in message and fake_key not in message
    fake_server.push(Raw(json.dumps(error)))
    fake_server.default = Reply(GOOD)
    assert _complete(built_plugins, fake_server, max_retries=1).text == GOOD


def test_an_error_object_without_a_message_and_a_4xx_keep_their_kinds(built_plugins, fake_server, fake_key):
    fake_server.default = Raw('{"error": {"type": "x"}}')
    with pytest.raises(BackendError, match=r"provider error in an HTTP 200 reply; provider said: \(no message\)"):
        _complete(built_plugins, fake_server)
    fake_server.default = Status(400, "bad request here")
    with pytest.raises(BackendError, match=r"request refused \(HTTP 400\).*bad request here"):
        _complete(built_plugins, fake_server, max_retries=2)


# (f) the reasoning the server sends apart ------------------------------------------------------

def test_reasoning_content_with_another_plan_is_refused_and_with_the_same_plan_accepted(built_plugins, fake_server,
                                                                                      fake_key):
    fake_server.default = Envelope([choice(GOOD, reasoning_content=f"I could go {OTHER} instead")])
    reply = _complete(built_plugins, fake_server)
    assert reply.text == GOOD and OTHER in reply.reasoning
    _refused(reply, "other than the answer")
    fake_server.default = Envelope([choice(GOOD, reasoning_content=f"Final answer: {GOOD}")])
    assert read_reply(_complete(built_plugins, fake_server)).control[0].angle == 30


def test_a_reflected_key_is_masked_from_the_reasoning_and_a_body_kept_whole(built_plugins, fake_server, fake_key):
    fake_server.default = Envelope([choice(GOOD, reasoning_content=f"sent with {fake_key}")],
                                   {"model": f"gpt-4o {fake_key}"})
    reply = _complete(built_plugins, fake_server)
    assert fake_key not in reply.reasoning and fake_key not in reply.model and "***" in reply.reasoning
    fake_server.default = Envelope([choice(GOOD), choice(f"echo {fake_key}", index=1)])
    reply = _complete(built_plugins, fake_server)
    assert reply.choices == 2 and fake_key not in reply.text


def test_a_reflected_key_is_masked_before_the_finish_reason_and_the_model_are_clipped(built_plugins, fake_key):
    long_key = "k" * 20 + fake_key + "X" * 40  # longer than both cuts, and no "sk-" shape for redact() to catch
    import os

    os.environ["SAFEEMBODAI_TEST_KEY"] = long_key
    try:
        with FakeOpenAI() as server:
            server.default = Envelope([choice(GOOD, finish_reason=long_key)], {"model": "m" * 40 + long_key})
            reply = _complete(built_plugins, server)
    finally:
        os.environ["SAFEEMBODAI_TEST_KEY"] = fake_key
    assert "***" in reply.finish_reason and reply.model.startswith("m" * 40)  # masked, then cut / made plain
    for field in (reply.finish_reason, reply.model):
        assert "k" * 12 not in field and fake_key[:8] not in field, field


def test_no_model_in_the_body_is_the_configured_model(built_plugins, fake_server, fake_key):
    fake_server.default = Envelope([choice(GOOD)],
                                   {"model": DROP, "usage": {"prompt_tokens": 7, "completion_tokens": 2}})
    reply = _complete(built_plugins, fake_server)
    assert reply.model == "gpt-4o" and (reply.usage.prompt_tokens, reply.usage.completion_tokens) == (7, 2)
    assert reply.latency_s > 0


# the transport itself ---------------------------------------------------------------------------

def test_a_body_over_4_mib_is_not_read_and_is_a_malformed_reply(built_plugins, fake_server, fake_key):
    fake_server.default = Raw(b'{"pad": "' + b"x" * (4 * 1024 * 1024) + b'"}')
    with pytest.raises(BackendError, match=r"gave up after 2 tries: malformed reply \(body too large"):
        _complete(built_plugins, fake_server, max_retries=3)
    assert len(fake_server.requests) == 2


def test_the_recorder_keeps_origin_status_and_body_and_never_a_header(fake_server, fake_key):
    from safeembodai_plugins.backends.litellm.transport import openai_client, recording

    fake_server.default = Reply(GOOD)
    client = openai_client(fake_server.url, fake_key, 5.0)
    try:
        with recording() as recorder:
            client.chat.completions.create(model="m", messages=[{"role": "user", "content": "x"}])
        [exchange] = recorder.exchanges
        assert (exchange.origin, exchange.status, exchange.location) == (_origin(fake_server), 200, None)
        assert json.loads(exchange.body)["choices"][0]["message"]["content"] == GOOD
        assert fake_key not in repr(recorder) and "authorization" not in repr(recorder).lower()
        assert fake_server.requests[0].headers["authorization"] == f"Bearer {fake_key}"
    finally:
        client.close()


def test_the_transport_sends_nothing_to_another_origin(fake_server):
    import httpx

    from safeembodai_plugins.backends.litellm.transport import RecordingTransport, recording

    with FakeOpenAI() as other, httpx.Client(transport=RecordingTransport(_origin(fake_server))) as client:
        with recording() as recorder, pytest.raises(httpx.TransportError, match="not the configured server"):
            client.post(other.url + "/chat/completions", json={})
        assert other.requests == [] and recorder.last.status is None


def test_only_openai_sdk_routes_get_the_strict_reading(built_plugins, fake_server, fake_key):
    from safeembodai_plugins.backends.litellm.client import strict_route
    from safeembodai_plugins.backends.litellm.runtime import import_litellm

    litellm = import_litellm()
    options = type("Options", (), {"api_base": None, "completion_kwargs": {}})
    for model, strict in [("gpt-4o", True), ("openai/local", True), ("anthropic/claude-3-5-sonnet-20240620", False),
                          ("no-such-provider/x", False),
                          # litellm calls these through the Responses API with its own client: not ours
                          ("gpt-5-pro", False), ("openai/o1-pro", False)]:
        options.model = model
        assert strict_route(options, litellm) is strict, model
    backend = _backend(built_plugins, fake_server, name="litellm", model="anthropic/claude-3-5-sonnet-20240620")
    assert backend._client is None and "sk-" not in repr(_backend(built_plugins, fake_server)._client)


def test_the_litellm_object_route_counts_choices_and_keeps_the_reasoning():
    from safeembodai_plugins.backends.litellm.reply import reply_from_response
    from safeembodai_plugins.backends.litellm.runtime import import_litellm

    litellm = import_litellm()
    response = litellm.ModelResponse(model="claude", choices=[
        {"index": 0, "finish_reason": "stop", "message": {"role": "assistant", "content": f"{GOOD} sk-secret-99",
                                                           "reasoning_content": f"maybe {OTHER}"}},
        {"index": 1, "finish_reason": "stop", "message": {"role": "assistant", "content": OTHER}}])
    reply = reply_from_response(response, "anthropic/claude", ["sk-secret-99"], 0.5)
    assert reply.choices == 2 and reply.origin is None and reply.finish_reason == "stop"
    assert OTHER in reply.reasoning and "sk-secret-99" not in reply.text and reply.model == "claude"
    _refused(reply, "2 choices")


def test_completion_kwargs_may_not_ask_for_several_answers_or_bring_a_client(built_plugins):
    for key, why in [("n", "one answer per call is read"), ("client", "follows no redirect")]:
        with pytest.raises(ComponentError, match=f"completion_kwargs may not set {key}.*{why}"):
            built_plugins.registry.build("llm_backend", "local", {"completion_kwargs": {key: 2}})


# the transport gives the core's strict reader's reply, for any generated body -------------------

def test_any_body_over_http_gives_the_strict_readers_reply(built_plugins, fake_key):
    """Whole replies (tests/support/reply_strategies.py) served over HTTP: the backend's reply is the one
    ``reply_from_chat_completion`` makes of the same body, so the verdicts of
    tests/core/models/test_chat_completion.py hold through the real transport too, for these bodies.
    (litellm itself fails the call on some bodies the reader would read -- a fraction as a token
    count -- as a malformed reply: those never reach a reading.)"""
    from hypothesis import HealthCheck, given, settings
    from reply_strategies import bodies

    from safeembodai_core.models.chat_completion import reply_from_chat_completion

    with FakeOpenAI() as server:
        backend = _backend(built_plugins, server)

        @settings(max_examples=40, deadline=None, suppress_health_check=[HealthCheck.too_slow])
        @given(generated=bodies())
        def check(generated):
            body, _ = generated
            server.push(Raw(body))
            got = backend.complete(_prompt(), np.random.default_rng(0))
            want = reply_from_chat_completion(body, origin=_origin(server))
            fields = ("text", "reasoning", "choices", "finish_reason", "envelope_error", "origin")
            assert {f: getattr(got, f) for f in fields} == {f: getattr(want, f) for f in fields}
            if want.usage_known:
                assert got.usage == want.usage
            else:  # the strict reading found no usable usage: the backend counted the call's tokens itself
                assert got.usage.estimated and got.usage.total > 0

        check()
