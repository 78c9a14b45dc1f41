"""The litellm backend against a hostile server: odd finish reasons, trickled replies, malformed
envelopes, absurd token counts, pydantic warnings and a server that reflects the key."""

from __future__ import annotations

import json
import threading
import warnings

import numpy as np
import pytest

from fake_openai import DROP, Envelope, Raw, Reply, Status, Trickle, choice
from safeembodai_core.errors import BackendError
from safeembodai_core.logs import redact
from safeembodai_core.models import Prompt, TextPart, read_reply
from safeembodai_core.models.chat_completion import read_usage
from safeembodai_core.models.reply import NORMAL_FINISH_REASONS, normal_finish_reason
from safeembodai_core.models.strict_json import ResponseParseError
from safeembodai_core.testing import answer, turn
from safeembodai_plugins.backends.litellm import call as litellm_call
from safeembodai_plugins.backends.litellm.errors import scrub_message

GOOD = answer(turn(30))
LATE = answer(turn(90, "right"), planning="late answer")


def _prompt() -> Prompt:
    return Prompt(system="Role: robot. JSON", user=(TextPart("user", 'Human Instruction: "go"'),))


def _backend(plugins, server, **options):
    base = {"api_base": server.url, "api_key_env": "SAFEEMBODAI_TEST_KEY", "backoff_s": 0.0, "backoff_max_s": 0.0,
            "timeout_s": 5.0, "max_retries": 0}
    return plugins.registry.build("llm_backend", "gpt-4o", {**base, **options})


def _complete(plugins, server, **options):
    return _backend(plugins, server, **options).complete(_prompt(), np.random.default_rng(0))


@pytest.mark.parametrize("sent,reported,accepted", [
    ("length", "length", False), ("stop", "stop", True), ("end_turn", "end_turn", True),
    ("max_tokens", "max_tokens", False), ("content_filter", "content_filter", False), ("STOP", "STOP", True),
    (" STOP ", " STOP ", None),  # None: as the core's one normalisation reads it, whatever that is
    ("no_such_reason_a_hostile_server_made_up", "no_such_reason_a_hostile_server_made_up", False),  # litellm: "stop"
    ("\x1b[2Jstop", "\x1b[2Jstop", False), ("stop\u200b", "stop\u200b", False), (7, "7", False),
    ("stop" + " " * 60 + "length", "stop" + " " * 60 + "[...]", False),  # clipped visibly: never a bare "stop"
    (None, None, True),  # a server that reports none: accepted (ControlLimits.require_finish_reason is off)
])
def test_finish_reason_is_the_providers_as_sent_clipped_at_64_and_judged_by_the_core(
        built_plugins, fake_server, fake_key, sent, reported, accepted):
    fake_server.default = Reply(GOOD, finish_reason=sent)
    reply = _complete(built_plugins, fake_server)
    assert reply.finish_reason == reported and reply.text == GOOD
    if accepted is None:
        accepted = normal_finish_reason(reported) in NORMAL_FINISH_REASONS
    if accepted:
        assert read_reply(reply).control[0].angle == 30
    else:
        with pytest.raises(ResponseParseError, match="finish reason"):
            read_reply(reply)


@pytest.mark.slow
def test_a_trickled_reply_past_the_deadline_times_out_and_is_never_used(built_plugins, fake_server, fake_key):
    # one byte every 0.1 s for 3 s: every read arrives within httpx's per-read timeout of 0.5 s
    fake_server.push(Trickle(3.0, 0.1, Reply(LATE)), Reply(GOOD))
    reply = _complete(built_plugins, fake_server, timeout_s=0.5, max_retries=1)
    assert reply.text == GOOD and len(fake_server.requests) == 2  # the timeout counted as a retry
    fake_server.push(Trickle(3.0, 0.1, Reply(LATE)), Trickle(3.0, 0.1, Reply(LATE)))
    with pytest.raises(BackendError, match=r"gave up after 2 tries: timed out") as raised:
        _complete(built_plugins, fake_server, timeout_s=0.5, max_retries=1)
    assert "late answer" not in str(raised.value)


def test_an_abandoned_call_never_hands_over_its_result_and_abandoned_calls_are_capped(monkeypatch):
    monkeypatch.setattr(litellm_call, "_abandoned", [])
    release = threading.Event()

    def hung(value):
        release.wait(10)
        return value

    try:
        for number in range(litellm_call.MAX_ABANDONED):
            with pytest.raises(litellm_call.CallTimedOut):
                litellm_call.call_with_deadline(hung, {"value": f"late {number}"}, 0.01)
        assert litellm_call.abandoned_alive() == litellm_call.MAX_ABANDONED
        with pytest.raises(litellm_call.TooManyHungCalls):
            litellm_call.call_with_deadline(lambda: "never started", {}, 1.0)
    finally:
        release.set()
        for worker in list(litellm_call._abandoned):
            worker.join(10)
    assert litellm_call.abandoned_alive() == 0
    assert litellm_call.call_with_deadline(lambda value: value, {"value": "fresh"}, 5.0) == "fresh"
    with pytest.raises(KeyError):  # an error inside the call is the caller's error
        litellm_call.call_with_deadline(lambda: {}["x"], {}, 5.0)


@pytest.mark.parametrize("body", ['{"choices": "x"}', "{}", "not json at all", '{"choices": [{"message": 5}]}',
                                  '{"choices": [{"index": 0, "message": {"content": {"a": 1}}}]}'])
def test_a_malformed_200_is_a_malformed_reply_retried_once_in_one_clean_line(built_plugins, fake_server, fake_key,
                                                                            body):
    fake_server.default = Raw(body)
    with pytest.raises(BackendError, match=r"gave up after 2 tries: malformed reply") as raised:
        _complete(built_plugins, fake_server, max_retries=3)
    message = str(raised.value)
    assert len(fake_server.requests) == 2
    assert "HTTP 500" not in message and "\n" not in message
    for internal in ("Traceback", 'File "', ".py", "site-packages", "<class"):
        assert internal not in message


def test_a_refused_200_was_paid_its_tokens_go_on_the_answer_or_on_the_give_up(built_plugins, fake_server,
                                                                              fake_key):
    """A whole 200 body the strict reading refused was answered, so paid: it counts (estimated) on the
    try that answers, or as ``BackendError.spent`` when the backend gives up. A 5xx is not billed."""
    fake_server.push(Raw("not json at all"), Reply(GOOD, usage=(1000, 150)))
    reply = _complete(built_plugins, fake_server, max_retries=3)
    assert reply.usage.prompt_tokens > 1000 and reply.usage.completion_tokens > 150 and reply.usage.estimated
    fake_server.default = Raw("not json at all")
    with pytest.raises(BackendError, match="gave up after 2 tries") as raised:
        _complete(built_plugins, fake_server, max_retries=3)
    assert raised.value.spent.estimated and raised.value.spent.prompt_tokens > 2 * 10
    fake_server.default = Status(500, "boom")
    with pytest.raises(BackendError) as raised:
        _complete(built_plugins, fake_server, max_retries=1)
    assert raised.value.spent is None


def test_a_call_abandoned_at_its_deadline_counts_as_the_most_it_can_have_cost(built_plugins, fake_server,
                                                                              fake_key):
    fake_server.default = Trickle(3.0, 0.1, Reply(LATE))
    with pytest.raises(BackendError, match="timed out") as raised:
        _complete(built_plugins, fake_server, timeout_s=0.5, max_tokens=300)
    spent = raised.value.spent
    assert spent.estimated and spent.prompt_tokens > 0 and spent.completion_tokens == 300


def test_a_real_server_error_is_still_a_server_error(built_plugins, fake_server, fake_key):
    fake_server.push(Raw("<html><body>Bad gateway\n  at /srv/app/proxy.py:12</body></html>", code=502,
                         content_type="text/html"), Status(500, "boom"))
    with pytest.raises(BackendError, match=r"gave up after 2 tries: server error \(HTTP 500\)"):
        _complete(built_plugins, fake_server, max_retries=1)


def test_scrubbed_provider_text_is_one_line_without_internals_or_secrets():
    text = ("litellm.InternalServerError: InternalServerError: OpenAIException - Invalid response object "
            "Traceback (most recent call last):\n  File \"/venv/lib/python3.11/site-packages/litellm/x.py\", "
            "line 3, in f\n    raise ValueError('sk-abcdefgh123456')\nValueError: boom")
    assert scrub_message(text) == "Invalid response object"
    dirty = "bad \x1b[31mkey\x1b[0m hunter2hunter2 in /etc/app/conf.py:7\r\nnext <class 'openai.X'> line"
    assert scrub_message(dirty, ["hunter2hunter2"]) == "bad [31mkey [0m *** in <path> next line"
    assert len(scrub_message("x" * 5000)) == 303


def test_absurd_token_counts_are_clamped_or_counted_here_and_never_raise(built_plugins, fake_server, fake_key):
    fake_server.default = Reply(GOOD, usage=(10**12, 5))
    reply = _complete(built_plugins, fake_server)
    assert (reply.usage.prompt_tokens, reply.usage.completion_tokens, reply.usage.estimated) == (2**31 - 1, 5, False)
    assert read_reply(reply).control[0].angle == 30
    # past the strict reader's bound on any number (1e15) the whole envelope is refused, never a crash;
    # the call was paid all the same, so its tokens are counted here, not taken as 0
    fake_server.default = Reply(GOOD, usage=(10**30, -5))
    reply = _complete(built_plugins, fake_server)
    assert reply.usage.estimated and reply.usage.prompt_tokens > 0
    assert "too large" in reply.envelope_error and GOOD.replace('"', '\\"') in reply.text
    with pytest.raises(ResponseParseError, match="refused as a whole"):
        read_reply(reply)
    for value, count in [({"prompt_tokens": 12, "completion_tokens": 3}, (12, 3)), ({"prompt_tokens": 12.0,
                         "completion_tokens": 3}, (12, 3)), ({"prompt_tokens": 10**400, "completion_tokens": 0},
                         (2**31 - 1, 0))]:
        usage = read_usage(value)
        assert (usage.prompt_tokens, usage.completion_tokens) == count, value
    for value in [None, "12", [1], {"prompt_tokens": -1, "completion_tokens": 3}, {"prompt_tokens": 12.9,
                  "completion_tokens": 3}, {"prompt_tokens": "12", "completion_tokens": 3}, {"total_tokens": 15},
                  {"prompt_tokens": True, "completion_tokens": 3},
                  {"prompt_tokens": float("nan"), "completion_tokens": 3},
                  {"prompt_tokens": 12}, {"prompt_tokens": 12, "completion_tokens": None}]:
        assert read_usage(value) is None, value


@pytest.mark.parametrize("usage", [DROP, None, {"prompt_tokens": -10, "completion_tokens": 5},
                                   {"prompt_tokens": 10.5, "completion_tokens": 5}, "many",
                                   {"total_tokens": 1150}, {"prompt_tokens": "1000", "completion_tokens": "150"},
                                   {"prompt_tokens": 0, "completion_tokens": 0}],
                         ids=["missing", "null", "negative", "fractional", "a string", "only total", "strings",
                              "zeros"])
def test_an_unusable_usage_is_counted_here_never_zero(built_plugins, fake_server, fake_key, usage):
    """Each of these must not count 0 tokens, or no spending cap would ever stop a run."""
    fake_server.default = Envelope([choice(GOOD)], {"usage": usage})
    reply = _complete(built_plugins, fake_server)
    assert reply.envelope_error is None and read_reply(reply).control[0].angle == 30
    assert reply.usage.estimated and reply.usage.prompt_tokens > 0 and reply.usage.completion_tokens > 0


def test_an_unreadable_usage_never_counts_less_than_the_server_said(built_plugins, fake_server, fake_key):
    """Fractional counts are unreadable, but the estimate (a few hundred tokens) must not replace a
    larger figure of the provider's own: each count is the larger of the two, rounded up."""
    fake_server.default = Envelope([choice(GOOD)], {"usage": {"prompt_tokens": 9000.9, "completion_tokens": 1.5}})
    reply = _complete(built_plugins, fake_server)
    assert reply.usage.estimated and reply.usage.prompt_tokens == 9001
    assert 2 <= reply.usage.completion_tokens < 1000  # the estimate of the answer: larger than 1.5 rounded up
    from safeembodai_core.models.chat_completion import said_usage

    said = said_usage({"prompt_tokens": 900.9, "completion_tokens": 120.5})
    assert (said.prompt_tokens, said.completion_tokens, said.estimated) == (901, 121, True)
    for nothing in (-3, float("nan"), "12", True, None):  # says nothing: the estimate alone
        assert said_usage({"prompt_tokens": nothing, "completion_tokens": nothing}).total == 0
    assert said_usage({"prompt_tokens": float("inf"), "completion_tokens": 1e300}).prompt_tokens == 2**31 - 1


def test_pydantic_warnings_about_an_odd_reply_never_reach_stderr(built_plugins, fake_server, fake_key, capfd):
    choice = '{"index": 0, "message": {"role": "assistant", "content": "%s"}, "finish_reason": "stop"%s}'
    fake_server.push(Raw('{"choices": [%s]}' % (choice % (GOOD.replace('"', '\\"'), ', "logprobs": "FRAGMENT-1"'))),
                     Raw('{"choices": [%s], "system_fingerprint": 5}' % (choice % ("FRAGMENT-2", ""))),
                     Raw('{"choices": [%s], "usage": {"prompt_tokens": "FRAGMENT-3"}}' % (choice % ("FRAGMENT-4", ""))))
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        assert _complete(built_plugins, fake_server).text == GOOD
        assert _complete(built_plugins, fake_server).text == "FRAGMENT-2"
        # litellm will not take that usage; the strict reading takes the reply and counts its tokens itself
        # (before, the call failed as malformed and was paid again)
        third = _complete(built_plugins, fake_server)
        assert third.text == "FRAGMENT-4" and third.usage.estimated and len(fake_server.requests) == 3
    assert [str(w.message) for w in caught if "FRAGMENT" in str(w.message) or "serializ" in str(w.message)] == []
    assert "FRAGMENT" not in capfd.readouterr().err


def test_a_reflected_key_is_masked_in_the_reply_and_registered_for_redaction(built_plugins, fake_server, fake_key):
    fake_server.default = Reply(lambda request: answer(turn(30), planning="I was sent " + json.dumps(request.headers)))
    backend = _backend(built_plugins, fake_server, completion_kwargs={
        "extra_headers": {"X-Api-Key": "hdr-secret-0123456789", "X-Trace": "trace-visible"}})
    reply = backend.complete(_prompt(), np.random.default_rng(0))
    assert fake_server.requests[0].headers["x-api-key"] == "hdr-secret-0123456789"  # really sent
    assert fake_key not in reply.text and "hdr-secret-0123456789" not in reply.text
    assert "Bearer ***" in reply.text and "trace-visible" in reply.text
    assert redact(f"echo {fake_key} and hdr-secret-0123456789") == "echo *** and ***"


def test_credentials_in_completion_kwargs_are_found_and_nothing_else():
    from safeembodai_plugins.backends.litellm.client import option_secrets

    found = option_secrets({"extra_headers": {"Authorization": "Bearer tok-123456789", "X-Trace": "visible-1"},
                            "aws_secret_access_key": "aws-secret-987654321", "azure_ad_token": "ad-token-55555",
                            "max_completion_tokens": 50, "tokenizer": "gpt2-visible", "top_p": 0.5})
    assert found == ["Bearer tok-123456789", "tok-123456789", "aws-secret-987654321", "ad-token-55555"]


@pytest.mark.parametrize("usage", [DROP, None, {"total_tokens": 1150}, {"prompt_tokens": 1000}],
                         ids=["missing", "null", "only total", "no completion"])
def test_a_route_litellm_parses_itself_does_not_turn_its_zero_filled_usage_into_a_free_call(
        built_plugins, fake_server, fake_key, usage):
    """Routes not read raw (``hosted_vllm/``, say) get litellm's usage object, which fills what the
    server left out with zeros: a call of 0 prompt tokens, or an answer of 0 tokens, is not believed."""
    fake_server.default = Envelope([choice(GOOD)], {"usage": usage})
    backend = built_plugins.registry.build("llm_backend", "litellm", {
        "model": "hosted_vllm/x", "api_base": fake_server.url, "api_key_env": "SAFEEMBODAI_TEST_KEY",
        "backoff_s": 0.0, "backoff_max_s": 0.0, "timeout_s": 5.0, "max_retries": 0})
    reply = backend.complete(_prompt(), np.random.default_rng(0))
    assert reply.usage.estimated and reply.usage.prompt_tokens > 0 and reply.usage.completion_tokens > 0
