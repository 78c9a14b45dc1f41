"""The options of the ``litellm`` backends (the package registers them)."""

from __future__ import annotations

import os
from typing import Any, Literal

from pydantic import Field, field_validator, model_validator

from safeembodai_core.contracts.descriptions import BackendDescription, BackendOptions
from safeembodai_core.errors import ComponentError

from ..json_modes import DEFAULT_MAX_TOKENS, LEGACY_JSON_MODES, JsonMode

_RESERVED = ("api_key", "messages", "model", "api_base", "base_url", "timeout", "max_retries", "num_retries", "n",
             "client", "stream")
# why an option is the backend's own, where "use the backend's own options" does not say it
_RESERVED_WHY = {
    "n": "one answer per call is read (n asks for several choices: several plans, none of which would run)",
    "client": "the backend brings its own client, which reads the reply strictly and follows no redirect",
    "stream": "the whole reply is read at once",
}
NO_KEY = "no-key-required"


#: litellm provider routes a model id may start with (``openai/`` reaches any OpenAI-compatible server).
ROUTES = frozenset({
    "openai", "azure", "azure_ai", "anthropic", "bedrock", "vertex_ai", "gemini", "mistral", "cohere", "groq",
    "together_ai", "fireworks_ai", "deepinfra", "deepseek", "openrouter", "perplexity", "xai", "huggingface",
    "ollama", "ollama_chat", "hosted_vllm", "vllm", "lm_studio", "llamafile", "openai_like", "custom_openai",
    "text-completion-openai", "litellm_proxy", "nvidia_nim", "cerebras", "sambanova", "watsonx", "databricks",
    "sagemaker", "replicate", "cloudflare", "github", "xinference", "oobabooga", "docker_model_runner",
})


def model_without_route(model_id: str) -> tuple[str, str | None]:
    """A litellm model id split into the model and litellm's provider route (None when it names none)."""
    route, _, rest = model_id.partition("/")
    if rest and route in ROUTES:
        return rest, route
    return model_id, None


class _LiteLLMOptions(BackendOptions):

    model: str = Field("gpt-4o", min_length=1, description="litellm model id")
    api_key_env: str | None = Field("OPENAI_API_KEY", description="environment variable holding the API key")
    api_base: str | None = Field(None, description="server URL, e.g. http://127.0.0.1:8080/v1")
    image_detail: Literal["low", "high", "auto"] = Field("low", description="vision detail of image parts")
    send_images: bool = Field(True, description="send image parts (off for text-only models)")
    fold_system_prompt: bool = Field(False, description="put the system prompt into the user turn")
    json_mode: JsonMode = Field("json_object", description="response_format sent")
    temperature: float | None = Field(None, ge=0.0, le=2.0, description="sampling temperature (None: provider's)")
    max_tokens: int = Field(1024, ge=16, le=32_768, description="most tokens in an answer")
    send_seed: bool = Field(False, description="send a per-attempt seed derived from the trial seed, step and attempt")
    retry_temperature_step: float = Field(0.0, ge=0.0, le=2.0,
                                          description="added to temperature for each retry of a step (capped at 2)")
    timeout_s: float = Field(60.0, gt=0, le=3600, description="per-request timeout")
    max_retries: int = Field(3, ge=0, le=20, description="retries on 429/5xx/timeouts/connection errors")
    backoff_s: float = Field(1.0, ge=0, le=600, description="first retry delay, doubled each retry")
    backoff_max_s: float = Field(30.0, ge=0, le=3600, description="longest delay between retries (and longest "
                                                                   "Retry-After honoured at once)")
    requests_per_minute: float | None = Field(None, gt=0, le=1_000_000,
                                              description="pace calls to this model (per run, shared by its trials)")
    tokens_per_minute: int | None = Field(None, gt=0, le=1_000_000_000,
                                          description="pace calls by the tokens answers use (per run)")
    rate_limit_wait_s: float = Field(600.0, ge=0, le=86_400,
                                     description="how long one call may wait out HTTP 429s before the trial fails "
                                                 "(429s do not count as retries)")
    drop_params: bool = Field(True, description="let litellm drop parameters a provider does not support")
    completion_kwargs: dict[str, Any] = Field(default_factory=dict, description="extra litellm.completion arguments")
    concurrency: int = Field(8, ge=1, le=256, description="trials in flight per worker when ablate is not given "
                                                           "--concurrency (a remote model: the run waits)")

    @field_validator("json_mode", mode="before")
    @classmethod
    def _current_name(cls, value: Any) -> Any:
        return LEGACY_JSON_MODES.get(value, value) if isinstance(value, str) else value

    @model_validator(mode="after")
    def _step_needs_a_temperature(self) -> "_LiteLLMOptions":
        if self.retry_temperature_step > 0 and self.temperature is None:
            raise ValueError("retry_temperature_step needs a temperature to step from; set temperature "
                             "(0.0 for a greedy first attempt)")
        return self

    @field_validator("api_key_env")
    @classmethod
    def _env_name(cls, value: str | None) -> str | None:
        if value is not None and (not value or not value.replace("_", "").isalnum()):
            raise ValueError(f"api_key_env must name an environment variable (letters, digits, _), got {value!r}; "
                             "put the key itself in that variable, never in the scenario")
        return value

    @field_validator("completion_kwargs")
    @classmethod
    def _not_reserved(cls, value: dict[str, Any]) -> dict[str, Any]:
        reserved = sorted(set(value) & set(_RESERVED))
        if reserved:
            why = "; ".join(f"{key}: {_RESERVED_WHY[key]}" for key in reserved if key in _RESERVED_WHY)
            raise ValueError(f"completion_kwargs may not set {', '.join(reserved)}: use the backend's own options "
                             "(the key comes from the variable named by api_key_env)" + (f"; {why}" if why else ""))
        return value

    def describe(self) -> BackendDescription:
        """The model without litellm's provider route (``openai/local`` is the model ``local`` behind an
        OpenAI-compatible server), said so; the replies name the model that answered."""
        model, route = model_without_route(self.model)
        unreported = "no reply named a model (or the run's results were not read)"
        source = (f"as configured; {unreported}" if route is None else
                  f"the configured litellm id `{self.model}` without its route `{route}/`; {unreported}")
        return BackendDescription(model=model, model_id=self.model, model_source=source, names_model_in_replies=True)


class LiteLLMOptions(_LiteLLMOptions):
    """Options of ``gpt-4o`` and ``litellm``."""


class LocalModelOptions(_LiteLLMOptions):
    """Options of ``local``: an OpenAI-compatible server, no key, the scenario's limits in the
    decoding schema, a greedy first attempt and retries that differ from it."""

    model: str = Field("openai/local", min_length=1, description="litellm model id (openai/<name> for any server)")
    api_key_env: str | None = Field(None, description="environment variable holding a key, if the server wants one")
    api_base: str | None = Field("http://127.0.0.1:8080/v1", description="the server's OpenAI-compatible URL")
    json_mode: JsonMode = Field("json_schema_enum", description="response_format sent (llama-cpp-python's form)")
    max_tokens: int = Field(DEFAULT_MAX_TOKENS, ge=16, le=32_768,
                            description="most tokens in an answer; the decoding schema's text caps fit inside it")
    temperature: float | None = Field(0.0, ge=0.0, le=2.0, description="sampling temperature of a step's first attempt")
    retry_temperature_step: float = Field(0.4, ge=0.0, le=2.0,
                                          description="added to temperature for each retry of a step (capped at 2)")
    send_seed: bool = Field(True, description="send a per-attempt seed derived from the trial seed, step and attempt")
    timeout_s: float = Field(300.0, gt=0, le=3600, description="per-request timeout")
    max_retries: int = Field(2, ge=0, le=20, description="retries on 429/5xx/timeouts/connection errors")
    concurrency: int = Field(1, ge=1, le=256, description="trials in flight per worker when ablate is not given "
                                                           "--concurrency (a server on this machine computes)")


def _api_key(name: str, options: _LiteLLMOptions, local: bool) -> str | None:
    if options.api_key_env is None:
        # a local server gets a placeholder so litellm never falls back to OPENAI_API_KEY
        return NO_KEY if local else None
    key = os.environ.get(options.api_key_env, "")
    if not key:
        raise ComponentError(f"llm backend {name!r}: environment variable {options.api_key_env} is not set; "
                             "export the API key there, or name another variable with the option api_key_env")
    return key
