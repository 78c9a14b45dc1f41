"""Logs go to stderr, stay quiet for library users, and never carry credentials."""

from __future__ import annotations

import subprocess
import sys

from safeembodai_core.logs import MASK, configure_logging, get_logger, redact


def test_library_use_prints_nothing_to_stdout():
    code = (
        "from safeembodai_core import run_guarded_trial\n"
        "from safeembodai_core.testing import CorridorWorld, answer, straight\n"
        "backend = {'use': 'scripted', 'options': {'responses': [answer(straight(399))]}}\n"
        "run_guarded_trial(CorridorWorld(wall_mm=600), backend, defences={'safety_validation': True}, max_steps=1)\n"
    )
    completed = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    assert completed.returncode == 0, completed.stderr
    assert completed.stdout == ""


def test_secrets_are_masked_by_key_and_by_shape(capsys):
    configure_logging("info")
    try:
        get_logger("test").info("calling", api_key="abc123", headers={"Authorization": "Bearer xyz"},
                                note="key sk-live1234567890abcdef used", prompt_tokens=120)
    finally:
        configure_logging("warning")
    err = capsys.readouterr().err
    assert "abc123" not in err and "xyz" not in err and "sk-live1234567890abcdef" not in err
    assert MASK in err and "prompt_tokens=120" in err


def test_redact_keeps_token_counts():
    assert redact({"total_tokens": 5, "token": "t0ps3cret"}) == {"total_tokens": 5, "token": MASK}


def test_registered_secrets_are_masked_in_any_logged_text(capsys):
    from safeembodai_core.logs import register_secret

    register_secret("opaque-credential-7f3a")
    configure_logging("info")
    try:
        get_logger("test").info("reply", planning="echo: opaque-credential-7f3a here")
    finally:
        configure_logging("warning")
    err = capsys.readouterr().err
    assert "opaque-credential-7f3a" not in err and MASK in err


def test_logged_llm_text_cannot_drive_the_terminal(capsys):
    configure_logging("info")
    try:
        get_logger("test").info("step.refused", reasons=["clear \x1b[2J screen", "clip \x1b]52;c;aGk=\x07", "nul \x00"])
    finally:
        configure_logging("warning")
    err = capsys.readouterr().err
    assert not any(char in err for char in "\x1b\x07\x00")
    assert "\\x1b[2J" in err
