"""Edges of the untrusted-answer path: secrets cut by a quotation or written with JSON escapes, padded
finish reasons, emoji codes in the step table (found in an adversarial review)."""

from __future__ import annotations

from safeembodai_core.guard.guard import Guard
from safeembodai_core.logs import MASK, redact, register_secret
from safeembodai_core.trust.quoting import quote_untrusted

TURN = '{"perception": [], "planning": "go", "control": [{"command": "turn", "direction": "left", "angle": 30}]}'
SECRET = "QQreviewSecret0123456789"


def test_a_clipped_quotation_never_leaves_part_of_a_secret():
    register_secret(SECRET)
    quoted = quote_untrusted("A" * 50 + SECRET, 60)
    assert SECRET[:8] not in quoted and MASK in quoted


def test_a_secret_written_with_json_escapes_is_masked():
    register_secret(SECRET)
    escaped = SECRET[:-1] + "\\u%04x" % ord(SECRET[-1])
    text = '{"planning": "' + escaped + '"}'
    masked = redact(text)
    assert SECRET[:-1] not in masked and MASK in masked
    assert redact('{"planning": "caf\\u00e9"}') == '{"planning": "caf\\u00e9"}'  # no secret: left as written


def test_padding_cannot_turn_an_abnormal_finish_reason_into_a_stop():
    guard = Guard()
    lidar = [2000.0] * 360
    assert guard.check_answer(TURN, lidar_mm=lidar, finish_reason="stop").valid
    assert not guard.check_answer(TURN, lidar_mm=lidar, finish_reason="stop" + " " * 60 + "length").valid


def test_the_step_table_keeps_emoji_codes_literal():
    from click.testing import CliRunner

    from safeembodai_core.cli import cli
    from safeembodai_core.testing import answer, turn

    plan = answer(turn(10)).replace('"planning": "plan"', '"planning": "go :warning: now"')
    scenario = {
        "name": "emoji", "max_steps": 1, "trials": 1,
        "environments": [{"use": "flatland"}],
        "backend": {"use": "scripted", "options": {"responses": [plan]}},
        "arms": {"a": {}}, "conditions": {"c": {}},
    }
    import json
    import tempfile
    from pathlib import Path

    with tempfile.TemporaryDirectory() as folder:
        path = Path(folder) / "s.yaml"
        path.write_text(json.dumps(scenario))
        result = CliRunner().invoke(cli, ["run", str(path), "--out", str(Path(folder) / "run")])
    assert ":warning:" in plan
    assert "\u26a0" not in result.output
    assert ":warning:" in result.output
