"""Hostile values through every entry point of the inventory (``safeembodai_core/trust.py``): each
reader returns what it documents or refuses with the project's own error -- never another exception,
never a hang. A new entry point gets its case here: the first test fails until it has one."""

from __future__ import annotations

import json
import math
import os
import sqlite3
import string
from pathlib import Path

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from safeembodai_core.errors import SafeEmbodAIError
from safeembodai_core.trust import ENTRY_POINTS

pytestmark = pytest.mark.slow

#: characters an attacker reaches for: controls, C1, bidi overrides, zero-width, tags, a BOM, surrogates' neighbours
HOSTILE_CHARS = "\x00\x07\x1b\x7f\x85\x9b\u200b\u200d\u202e\u2066\ufeff\U000e0041\uffff" + '{}[]",:\\ntrue1e309-'
hostile_text = st.text(alphabet=st.sampled_from(HOSTILE_CHARS) | st.characters(), max_size=300)
numbers = st.sampled_from(["1e309", "-1e309", "NaN", "Infinity", "-0", "1e-400", "9" * 400, "0x10", "1_000", "+1"])


@st.composite
def json_ish(draw) -> str:
    """Text that is almost JSON: duplicate keys, numbers at the limits, deep nesting, two values, a BOM."""
    kind = draw(st.sampled_from(["dup", "number", "deep", "two", "bom", "value", "text"]))
    if kind == "dup":
        key = draw(st.text(max_size=5))
        return "{" + json.dumps(key) + ":1," + json.dumps(key) + ":" + draw(numbers) + "}"
    if kind == "number":
        return '{"text": "x", "usage": {"prompt_tokens": ' + draw(numbers) + "}}"
    if kind == "deep":
        depth = draw(st.integers(100, 20_000))
        return "[" * depth + "]" * draw(st.integers(0, depth))
    if kind == "two":
        return "{} {}"
    if kind == "bom":
        return "\ufeff" + json.dumps({"a": 1})
    if kind == "value":
        value = draw(st.recursive(st.none() | st.booleans() | st.floats() | st.integers() | hostile_text,
                                  lambda inner: st.lists(inner, max_size=4) | st.dictionaries(hostile_text, inner,
                                                                                               max_size=4),
                                  max_leaves=20))
        return json.dumps(value)
    return draw(hostile_text)


def refuses_cleanly(call):
    """Run ``call``; a refusal must be the project's own error (a reader's :class:`ResponseParseError`
    is the strict JSON readers' documented refusal)."""
    from safeembodai_core.models.strict_json import ResponseParseError

    try:
        return call()
    except (SafeEmbodAIError, ResponseParseError):
        return None


FUZZ = settings(max_examples=150, deadline=None, suppress_health_check=list(HealthCheck))


def case_llm_reply(text: str) -> None:
    from safeembodai_core.models.reply import BackendReply, read_reply

    refuses_cleanly(lambda: read_reply(BackendReply(text=text)))


def case_llm_envelope(text: str) -> None:
    from safeembodai_core.models.chat_completion import reply_from_chat_completion

    reply = reply_from_chat_completion(text.encode("utf-8", "surrogatepass"))  # documented: never raises
    assert isinstance(reply.text, str)


def case_server_usage(text: str) -> None:
    from safeembodai_core.models.chat_completion import read_usage

    try:
        value = json.loads(text)
    except (ValueError, RecursionError):
        value = text
    usage = read_usage(value if isinstance(value, dict) else {"prompt_tokens": value, "completion_tokens": value})
    assert usage is None or (usage.prompt_tokens >= 0 and usage.completion_tokens >= 0)


def case_cached_reply(text: str) -> None:
    from safeembodai_core.loop.response_cache import stored_reply

    reply = stored_reply(text)
    assert reply is None or ("\x1b" not in reply.model and "\n" not in (reply.envelope_error or ""))


def case_bag_plan(text: str) -> None:
    from safeembodai_core.models.strict_json import read_json_document

    refuses_cleanly(lambda: read_json_document(text))


def case_scenario_file(text: str, folder: Path) -> None:
    from safeembodai_core.scenario.limits import read_scenario_text
    from safeembodai_core.scenario.loader import parse_scenario

    path = folder / "s.yaml"
    path.write_text(text, encoding="utf-8", errors="surrogatepass")
    refuses_cleanly(lambda: parse_scenario(read_scenario_text(path)))


def case_robot_file(text: str, folder: Path) -> None:
    from safeembodai_core.ros.robot_file import read_robot_file

    path = folder / "robot.yaml"
    path.write_text(text, encoding="utf-8", errors="surrogatepass")
    refuses_cleanly(lambda: read_robot_file(path))


def case_guard_mcp_policy(text: str, folder: Path) -> None:
    from safeembodai_core.guard_mcp.policy import read_policy

    path = folder / "policy.yaml"
    path.write_text(text, encoding="utf-8", errors="surrogatepass")
    refuses_cleanly(lambda: read_policy(path))


def case_mcp_tool_call(text: str) -> None:
    from safeembodai_core.guard_mcp.calls import Forward, Motion, read_call
    from safeembodai_core.guard_mcp.policy import read_policy

    try:
        value = json.loads(text)
    except (ValueError, RecursionError):
        value = text
    policy = read_policy()
    for tool in ("publish_once", "publish_for_durations", "call_service", "connect_to_robot", "ping_robots", text[:20]):
        for arguments in (value, {"topic": "/cmd_vel", "msg_type": "geometry_msgs/msg/Twist", "msg": value},
                          {"topic": "/cmd_vel", "msg_type": "geometry_msgs/msg/Twist", "messages": [value],
                           "durations": [value]}, {"ip": value, "port": value}, {"targets": value}):
            read = refuses_cleanly(lambda: read_call(tool, arguments, policy, ("127.0.0.1", 9090)))
            assert read is None or isinstance(read, (Motion, Forward))
            if isinstance(read, Motion):  # what is judged is finite, and what is forwarded is that twist
                assert all(math.isfinite(h.twist.linear_x) and math.isfinite(h.twist.angular_z) for h in read.holds)


def case_mcp_tool_result(text: str) -> None:
    pytest.importorskip("mcp", reason="guard-mcp needs the MCP SDK: pip install -e '.[mcp]'")
    from mcp import types

    from safeembodai_core.guard_mcp.agent import mark_untrusted

    text = text.encode("utf-8", "replace").decode("utf-8")  # the SDK hands over decoded JSON strings
    result = types.CallToolResult(content=[types.TextContent(type="text", text=text)],
                                  structuredContent={"msg": {"data": text}}, isError=False)
    marked = mark_untrusted("subscribe_once", result)  # documented: never raises
    assert json.loads(marked.content[1].text) == text or "***" in marked.content[1].text  # a secret redacted
    assert not {"\n", "\x1b", "\u202e", "\u2028"} & set(marked.content[1].text)  # nothing breaks its line
    assert marked.structuredContent["untrusted_data"] == {"msg": {"data": text}}


def case_run_folder_file(text: str, folder: Path) -> None:
    from safeembodai_core.ablation.run_folder import RunFolder

    (folder / "scenario.json").write_text(text, encoding="utf-8", errors="surrogatepass")
    refuses_cleanly(lambda: RunFolder(folder).scenario())
    (folder / "finished.jsonl").write_text(text, encoding="utf-8", errors="surrogatepass")
    ids = refuses_cleanly(lambda: RunFolder(folder).finished())
    assert ids is None or all(isinstance(i, str) for i in ids)


def case_run_folder_picture(text: str, folder: Path) -> None:
    from safeembodai_core.run_files import read_regular_file

    path = folder / "p.png"
    path.write_bytes(text.encode("utf-8", "surrogatepass"))
    assert read_regular_file(path, 100) in (None, path.read_bytes())


def case_results_store(text: str, folder: Path) -> None:
    from safeembodai_plugins.state.sqlite_db import SqliteStateStore

    path = folder / "results.sqlite"
    store = SqliteStateStore(path)
    store.close()
    conn = sqlite3.connect(path)
    conn.execute("INSERT OR REPLACE INTO trials VALUES ('t', 's', 'e', 'a', 'c', 0, 0, 'finished', 'completed', 1, "
                 "'{}', ?)", (text,))
    conn.execute("INSERT OR REPLACE INTO steps VALUES ('t', 1, 1, 0, 0, 0, 0, ?)", (text,))
    conn.commit()
    conn.close()
    store = SqliteStateStore(path, readonly=True)
    try:
        refuses_cleanly(store.results)
        refuses_cleanly(lambda: store.steps("t"))
    finally:
        store.close()


def case_ray_worker_event(text: str, folder: Path) -> None:
    from safeembodai_core.ablation.relay import RelayedWrites
    from safeembodai_core.loop.response_cache import ResponseCache
    from safeembodai_core.models import TrialSpec
    from safeembodai_plugins.state.memory_store import MemoryStateStore

    spec = TrialSpec(trial_id="E/a/c/0", scenario="s", environment="E", arm="a", condition="c", index=0, seed=0)
    writes = RelayedWrites(MemoryStateStore(), str(folder), ResponseCache(folder / "responses"))
    try:
        payload = json.loads(text)
    except (ValueError, RecursionError):
        payload = text
    for kind in ("node", "begin", "step", "reply", "end", "done", "picture", "bag", "failed", text[:10]):
        for event in ((kind, payload), (kind, "k" * 64 + ":0", text), (kind, {text[:20]: text.encode()})):
            refuses_cleanly(lambda: writes.receive(spec, event))
    assert not any(p.is_symlink() for p in folder.rglob("*"))


def case_inspect_model_output(text: str) -> None:
    inspect_ai = pytest.importorskip("inspect_ai", reason='needs the inspect extra: pip install -e ".[inspect]"')
    from inspect_ai.model import StopDetails

    from safeembodai_core.integrations.inspect.bridge import REFUSED_REPLY, backend_reply
    from safeembodai_core.models.reply import read_reply

    for details in (None, StopDetails(type=REFUSED_REPLY, explanation=text), StopDetails(type=text[:20])):
        output = inspect_ai.model.ModelOutput.from_content("m", text, stop_reason="stop", stop_details=details)
        reply = backend_reply(output, 0.0)
        assert "\x1b" not in (reply.envelope_error or "") and "\n" not in (reply.envelope_error or "")
        refuses_cleanly(lambda: read_reply(reply))


def case_inspect_usage(text: str) -> None:
    inspect_ai = pytest.importorskip("inspect_ai", reason='needs the inspect extra: pip install -e ".[inspect]"')
    from safeembodai_core.integrations.inspect.bridge import output_usage

    try:
        value = json.loads(text)
    except (ValueError, RecursionError):
        value = text
    output = inspect_ai.model.ModelOutput.from_content("m", "answer")
    output.usage = inspect_ai.model.ModelUsage.model_construct(input_tokens=value, output_tokens=value)
    usage = output_usage(output, None)
    assert usage.prompt_tokens > 0 and usage.completion_tokens > 0  # never 0: read, or counted here


def case_inspect_provider(text: str) -> None:
    pytest.importorskip("inspect_ai", reason='needs the inspect extra: pip install -e ".[inspect]"')
    from safeembodai_core.integrations.inspect.providers import ProviderRefused, check_provider

    try:
        check_provider(text)
    except ProviderRefused as refused:
        assert "\x1b" not in str(refused) and "\u202e" not in str(refused)
    else:
        assert text.split("/")[0] in ("safeembodai", "mockllm")


def case_rosbridge_frame(text: str) -> None:
    from safeembodai_core.rosbridge.frames import FrameError, read_frame

    try:
        read_frame(text)
    except FrameError as refused:  # quoted when it cites the frame: no raw control character
        assert "\x1b" not in str(refused) and "\u202e" not in str(refused)


TEXT_CASES = {"llm reply": case_llm_reply, "llm envelope": case_llm_envelope, "server usage": case_server_usage,
              "cached reply": case_cached_reply, "bag plan": case_bag_plan,
              "inspect model output": case_inspect_model_output, "inspect usage": case_inspect_usage,
              "inspect provider": case_inspect_provider, "rosbridge frame": case_rosbridge_frame,
              "mcp tool call": case_mcp_tool_call, "mcp tool result": case_mcp_tool_result}
FILE_CASES = {"scenario file": case_scenario_file, "robot file": case_robot_file,
              "guard-mcp policy": case_guard_mcp_policy,
              "run folder file": case_run_folder_file,
              "run folder picture": case_run_folder_picture, "results store": case_results_store,
              "ray worker event": case_ray_worker_event}


def test_every_entry_point_has_a_fuzz_case():
    assert {entry.name for entry in ENTRY_POINTS} == set(TEXT_CASES) | set(FILE_CASES)


@pytest.mark.parametrize("name", sorted(TEXT_CASES))
def test_hostile_text_through_each_reader(name):
    @FUZZ
    @given(text=json_ish())
    def run(text):
        TEXT_CASES[name](text)

    run()


@pytest.mark.parametrize("name", sorted(FILE_CASES))
def test_hostile_files_through_each_reader(name, tmp_path_factory):
    @FUZZ
    @given(text=json_ish())
    def run(text):
        FILE_CASES[name](text, tmp_path_factory.mktemp("fuzz"))

    run()


@pytest.mark.parametrize("kind", ["fifo", "symlink", "folder", "device", "large"])
def test_files_that_are_not_plain_files_are_refused_at_once(tmp_path, kind):
    """Every run-folder reader meets a FIFO, a symlink to a secret, a folder, a device and a sparse 10 GB file."""
    from safeembodai_core.run_files import read_regular_file, read_run_text

    target = tmp_path / "scenario.json"
    if kind == "fifo":
        os.mkfifo(target)
    elif kind == "symlink":
        (tmp_path / "secret").write_text("{}")
        target.symlink_to(tmp_path / "secret")
    elif kind == "folder":
        target.mkdir()
    elif kind == "device":
        target.symlink_to("/dev/zero")
    else:
        with target.open("wb") as handle:
            handle.truncate(10 * 1024**3)
    assert read_regular_file(target, 1_000_000) is None
    with pytest.raises(SafeEmbodAIError, match="unreadable"):
        read_run_text(target, 1_000_000)


def test_the_alphabet_is_hostile():
    assert set("\x1b\u202e\u200b\ufeff") <= set(HOSTILE_CHARS) and not set(HOSTILE_CHARS) <= set(string.printable)
