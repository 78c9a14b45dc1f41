"""LLM backends through litellm: ``gpt-4o``, ``litellm`` (any model id) and ``local``.

* ``gpt-4o`` -- OpenAI's GPT-4o, the paper's model: camera and LiDAR images as base64 image
  parts, JSON output requested, key from ``OPENAI_API_KEY``.
* ``litellm`` -- the same for any model id litellm knows (``anthropic/...``, ``azure/...``);
  name the key's environment variable with ``api_key_env``.
* ``local`` -- any OpenAI-compatible server (llama.cpp, vLLM, Ollama) at ``api_base``; a JSON
  schema carrying the scenario's actuation limits is sent for constrained decoding, in the form
  ``json_mode`` names (:func:`.messages.response_format`); no key unless ``api_key_env`` names one.

Retries of a step can differ from its first attempt: each attempt sends its own seed
(``send_seed``) and, with ``retry_temperature_step``, a temperature raised by that much per retry
-- at temperature 0 a seed changes nothing, and a greedy retry repeats the refused answer word
for word. What an attempt sent is recorded in its ``Attempt.sampling``.

The API key is read from the environment when the backend is built (not when it is built only to
quote a price: ``BuildContext.only_to_describe``) and is never stored in options, logs, records or
reports. litellm is imported by the implementation module only. Every option is documented in
``docs/backends.md``.
"""

from __future__ import annotations

from safeembodai_core.hookspecs import hookimpl

from .options import NO_KEY, LiteLLMOptions, LocalModelOptions, _api_key, _LiteLLMOptions


def _factory(name: str, local: bool = False):
    def build(options: _LiteLLMOptions, context):
        from .client import LiteLLMBackend

        if context is not None and context.only_to_describe:  # a price or a description: no call, no key
            return LiteLLMBackend(name, options, NO_KEY)
        return LiteLLMBackend(name, options, _api_key(name, options, local))

    return build


@hookimpl
def register_llm_backends(register):
    register("gpt-4o", _factory("gpt-4o"), options=LiteLLMOptions,
             description="OpenAI GPT-4o (or any litellm model id) with camera and LiDAR images")
    register("litellm", _factory("litellm"), options=LiteLLMOptions,
             description="any litellm model id; set model and api_key_env")
    register("local", _factory("local", local=True), options=LocalModelOptions,
             description="OpenAI-compatible local server (llama.cpp, vLLM, Ollama) at api_base")
