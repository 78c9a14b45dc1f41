"""A text-only model sent images: the error says so plainly and names ``perception: text``.

llama-cpp-python serving SmolLM2 (no vision) fails in its chat template on a list of content parts
and answers HTTP 500 "can only concatenate str (not list) to str"; other servers say it in words.
"""

from __future__ import annotations

import json

import numpy as np
import pytest

from fake_openai import Raw, Reply, Status
from safeembodai_core.errors import BackendError
from safeembodai_core.models import ImagePart, Prompt, TextPart
from safeembodai_core.testing import answer, turn
from safeembodai_plugins.backends.litellm.errors import (ERROR_IN_200, SERVER_ERROR, TEXT_ONLY, Failure,
                                                         images_refused)

LLAMA_CPP_500 = json.dumps({"error": {"message": "can only concatenate str (not list) to str"}})
PNG = b"\x89PNG\r\n\x1a\nfake-image"


def _prompt() -> Prompt:
    return Prompt(system="Role: robot. JSON", user=(TextPart("user", 'Human Instruction: "go"'),
                                                    ImagePart("camera_image", PNG), ImagePart("lidar_image", PNG)))


def _local(plugins, server, **options):
    base = {"api_base": server.url, "backoff_s": 0.0, "backoff_max_s": 0.0, "timeout_s": 5.0, "max_retries": 2}
    return plugins.registry.build("llm_backend", "local", {**base, **options})


def test_a_text_only_server_failing_on_images_says_use_the_text_perception_at_once(built_plugins, fake_server):
    fake_server.default = Raw(LLAMA_CPP_500, code=500)
    with pytest.raises(BackendError) as raised:
        _local(built_plugins, fake_server).complete(_prompt(), np.random.default_rng(0))
    message = str(raised.value)
    assert "this model does not take images" in message
    assert "`perception: text`" in message
    assert "gave up after 1 try" in message  # not retried: the same request fails the same way
    assert "can only concatenate str (not list) to str" in message  # the server's own words stay
    [request] = fake_server.requests
    [user] = [m for m in request.body["messages"] if m["role"] == "user"]
    assert any(part["type"] == "image_url" for part in user["content"])


def test_the_perception_the_message_names_is_the_registered_text_only_one(built_plugins):
    assert "text" in built_plugins.registry.names("perception")
    assert "`perception: text`" in TEXT_ONLY


def test_the_same_error_without_images_in_the_request_stays_a_server_error(built_plugins, fake_server):
    fake_server.default = Raw(LLAMA_CPP_500, code=500)
    with pytest.raises(BackendError) as raised:
        _local(built_plugins, fake_server, send_images=False).complete(_prompt(), np.random.default_rng(0))
    assert "server error (HTTP 500)" in str(raised.value) and "does not take images" not in str(raised.value)


def test_a_text_only_server_answering_without_images_still_works(built_plugins, fake_server):
    fake_server.push(Reply(answer(turn(30))))
    reply = _local(built_plugins, fake_server, send_images=False).complete(_prompt(), np.random.default_rng(0))
    assert reply.text == answer(turn(30))


@pytest.mark.parametrize("status,text", [
    (500, 'can only concatenate str (not "list") to str'),
    (500, "image input is not supported - hint: if this is unexpected, you may need to provide the mmproj"),
    (400, "Qwen2ForCausalLM is not a multimodal model"),
    (400, "Invalid content type. image_url is only supported by certain models."),
    (400, "Model does not support images. Please use a model that does."),
    (422, "this model doesn't support vision input"),
])
def test_servers_saying_no_images_in_their_own_words(status, text):
    failure = images_refused(Failure(f"{SERVER_ERROR} (HTTP {status})", True, text), status, True)
    assert failure.kind == TEXT_ONLY and not failure.retryable and failure.detail == text


@pytest.mark.parametrize("failure,status,images", [
    (Failure(f"{SERVER_ERROR} (HTTP 500)", True, "CUDA out of memory"), 500, True),  # another 500
    (Failure(f"{SERVER_ERROR} (HTTP 500)", True, "can only concatenate str (not list) to str"), 500, False),
    (Failure(f"{SERVER_ERROR} (HTTP 503)", True, "image input is not supported"), 503, True),  # overloaded
    (Failure("rate limited (HTTP 429)", True, "image input is not supported"), 429, True),
])
def test_other_failures_are_left_as_they_were(failure, status, images):
    assert images_refused(failure, status, images) == failure


def test_an_error_object_in_an_http_200_naming_images_is_recognised_too(built_plugins, fake_server):
    fake_server.default = Raw(json.dumps({"error": {"message": "image input is not supported"}}), code=200)
    with pytest.raises(BackendError, match="gave up after 1 try: this model does not take images"):
        _local(built_plugins, fake_server).complete(_prompt(), np.random.default_rng(0))
    assert images_refused(Failure(ERROR_IN_200, True, "image input is not supported"), 200, True).kind == TEXT_ONLY


def test_a_plain_server_error_on_an_image_request_keeps_its_retries(built_plugins, fake_server):
    fake_server.push(Status(500, "boom"), Reply(answer(turn(30))))
    reply = _local(built_plugins, fake_server).complete(_prompt(), np.random.default_rng(0))
    assert reply.text == answer(turn(30)) and len(fake_server.requests) == 2
