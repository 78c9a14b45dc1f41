"""The prompt outline shows numbers as numbers, the decoding schema carries the scenario's
limits, the default ``json_mode`` of ``local`` is the form the llama-cpp-python server reads, a
server error that repeats word for word stops the retries, and a step's retries can differ from its
first attempt."""

from __future__ import annotations

import json

import numpy as np
import pytest

from backend_helpers import one_trial_steps
from fake_openai import Reply, Status
from safeembodai_core.errors import BackendError, ComponentError
from safeembodai_core.models import ControlLimits, Prompt, TextPart, parse_response
from safeembodai_core.models.response import schema_outline
from safeembodai_core.testing import answer, straight, turn
from safeembodai_plugins.backends.messages import bounded_number, decoding_schema, response_format

LIMITS = ControlLimits(max_distance_mm=250, max_angle_deg=45, max_signals=2)
GOOD = answer(turn(30))


def _prompt() -> Prompt:
    return Prompt(system="S", user=(TextPart("user", "U"),))


def _local(plugins, server, **options):
    base = {"api_base": server.url, "backoff_s": 0.0, "backoff_max_s": 0.0, "timeout_s": 5.0}
    return plugins.registry.build("llm_backend", "local", {**base, **options})


def _numbers(schema):
    return schema["$defs"]["Straight"]["properties"]["distance"], schema["$defs"]["Turn"]["properties"]["angle"]


def test_the_range_form_carries_the_limits_as_integer_bounds():
    schema = decoding_schema(LIMITS, "range")
    assert _numbers(schema) == ({"type": "integer", "minimum": 1, "maximum": 249},
                                {"type": "integer", "minimum": 1, "maximum": 44})
    assert schema["properties"]["control"]["maxItems"] == 2


def test_the_enum_form_lists_every_allowed_whole_value():
    distance, angle = _numbers(decoding_schema(LIMITS, "enum"))
    assert distance == {"type": "integer", "enum": list(range(1, 250))}
    assert angle["enum"] == list(range(1, 45))
    assert _numbers(decoding_schema(bounds="enum"))[0]["enum"][-1] == 399  # the paper's 0 < d < 400


def test_a_huge_limit_is_sampled_and_a_tiny_one_falls_back_to_exclusive_bounds():
    values = bounded_number(5000.0, "enum")["enum"]
    assert len(values) <= 400 and values[-1] < 5000 and values[0] > 0
    assert bounded_number(0.5, "enum") == {"type": "number", "exclusiveMinimum": 0, "exclusiveMaximum": 0.5}
    assert bounded_number(400.5, "range")["maximum"] == 400


@pytest.mark.parametrize("bounds", ["range", "enum"])
def test_every_value_the_schema_allows_the_contract_accepts(bounds):
    distance, angle = _numbers(decoding_schema(LIMITS, bounds))
    top_d = distance.get("maximum", max(distance.get("enum", [0])))
    top_a = angle.get("maximum", max(angle.get("enum", [0])))
    assert parse_response(answer(straight(top_d), turn(top_a)), LIMITS).control[0].distance == 249
    assert parse_response(answer(straight(1), turn(1)), LIMITS)


def test_response_formats_by_mode():
    assert response_format("json_schema_enum", LIMITS) == {"type": "json_object",
                                                           "schema": decoding_schema(LIMITS, "enum")}
    assert response_format("json_schema", LIMITS)["json_schema"]["schema"] == decoding_schema(LIMITS, "range")
    assert response_format("json_object") == {"type": "json_object"}
    assert response_format("none") is None


def test_old_mode_names_still_validate(built_plugins):
    options = built_plugins.registry.get("llm_backend", "local").options
    assert options(json_mode="json_object_schema").json_mode == "json_schema_enum"
    assert options(json_mode="off").json_mode == "none"
    assert options().json_mode == "json_schema_enum"


def test_a_trial_sends_the_scenarios_limits_and_records_differing_retries(built_plugins, fake_server):
    fake_server.push(Reply(answer(straight(300))), Reply(answer(straight(300))))  # 300 >= the 250 mm limit
    fake_server.default = Reply(GOOD)
    data = {
        "name": "limits", "trials": 1, "max_steps": 1, "seed": 5, "environments": ["flatland"], "state": "memory",
        "perception": "text", "limits": {"max_distance_mm": 250, "max_angle_deg": 45, "max_signals": 2},
        "backend": {"use": "local", "options": {"api_base": fake_server.url, "timeout_s": 5.0}},
        "arms": {"safeembodai": {"security_prefix": True, "state_management": True, "safety_validation": True,
                                 "failure_threshold": 3}},
        "conditions": {"no_attack": {}},
    }
    [step] = one_trial_steps(built_plugins, data, "safeembodai")
    bodies = [r.body for r in fake_server.requests]
    assert len(bodies) == 3 and [a.accepted for a in step.attempts] == [False, False, True]
    for body in bodies:
        schema = body["response_format"]["schema"]
        assert _numbers(schema)[0]["enum"][-1] == 249 and schema["properties"]["control"]["maxItems"] == 2
    assert [b["temperature"] for b in bodies] == [0.0, 0.4, 0.8]
    assert len({b["seed"] for b in bodies}) == 3
    assert [a.sampling for a in step.attempts] == [{"temperature": b["temperature"], "seed": b["seed"]}
                                                  for b in bodies]


def test_the_same_server_error_twice_on_the_same_request_is_not_retried_again(built_plugins, fake_server):
    refusal = "1 validation error: loc ('body', 'response_format', 'type') Input should be 'text' or 'json_object'"
    fake_server.default = Status(500, refusal)
    backend = _local(built_plugins, fake_server, json_mode="json_schema", max_retries=5)
    with pytest.raises(BackendError, match=r"gave up after 2 tries: server error \(HTTP 500\), the same twice "
                                           r".*json_mode 'json_schema'"):
        backend.complete(_prompt(), np.random.default_rng(0))
    assert len(fake_server.requests) == 2


def test_differing_server_errors_keep_their_retries(built_plugins, fake_server):
    fake_server.push(Status(503, "overloaded 1"), Status(503, "overloaded 2"), Reply(GOOD))
    assert _local(built_plugins, fake_server, max_retries=3).complete(_prompt(), np.random.default_rng(0)).text == GOOD


def test_a_temperature_step_needs_a_temperature(built_plugins):
    with pytest.raises(ComponentError, match="retry_temperature_step needs a temperature"):
        built_plugins.registry.build("llm_backend", "local", {"temperature": None})


def test_without_prepare_attempt_the_first_attempts_sampling_is_sent(built_plugins, fake_server):
    fake_server.default = Reply(GOOD)
    _local(built_plugins, fake_server).complete(_prompt(), np.random.default_rng(0))
    body = fake_server.requests[0].body
    assert body["temperature"] == 0.0 and isinstance(body["seed"], int)
    assert json.dumps(body["response_format"]["schema"]).count('"enum"') >= 2


def test_schema_outline_shows_numbers_as_numbers_inside_the_contract():
    straight_entry, turn_entry = json.loads(schema_outline())["control"]
    assert (straight_entry["distance"], turn_entry["angle"]) == (200, 45)  # never "number (millimetres)"
    assert '"distance":"' not in schema_outline() and '"angle":"' not in schema_outline()
    tight = ControlLimits(max_distance_mm=150, max_angle_deg=1)
    straight_entry, turn_entry = json.loads(schema_outline(tight))["control"]
    assert (straight_entry["distance"], turn_entry["angle"]) == (75, 0.5)
    copied = [{**straight_entry, "direction": "forward"}, {**turn_entry, "direction": "left"}]
    assert parse_response(json.dumps({**json.loads(schema_outline(tight)), "control": copied}), tight)
