"""Hostile values through every entry point of the inventory (``safeembodai_core/trust/inventory.py``): each
reader returns what it documents or refuses with the project's own error -- never another exception,
never a hang. A new entry point gets its case here: the first test fails until it has one."""

from __future__ import annotations

import gc
import json
import math
import os
import re
import socket
import sqlite3
import string
import threading
import time
import tracemalloc
from pathlib import Path
from types import SimpleNamespace
from typing import Any

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from safeembodai_core.errors import SafeEmbodAIError
from safeembodai_core.trust.inventory import ENTRY_POINTS

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
    from safeembodai_core.runs.folder import RunFolder

    (folder / "scenario.json").write_text(text, encoding="utf-8", errors="surrogatepass")
    refuses_cleanly(lambda: RunFolder(folder).scenario())
    (folder / "finished.jsonl").write_text(text, encoding="utf-8", errors="surrogatepass")
    ids = refuses_cleanly(lambda: RunFolder(folder).finished())
    assert ids is None or all(isinstance(i, str) for i in ids)


def case_run_folder_picture(text: str, folder: Path) -> None:
    from safeembodai_core.runs.files import read_regular_file

    path = folder / "p.png"
    path.write_bytes(text.encode("utf-8", "surrogatepass"))
    assert read_regular_file(path, 100) in (None, path.read_bytes())


def case_results_store(text: str, folder: Path) -> None:
    from safeembodai_plugins.state.sqlite_db import SqliteStateStore

    path = folder / "results.sqlite"
    store = SqliteStateStore(path)
    store.close()
    try:  # sqlite3 cannot bind a lone surrogate as text: a forged file holds its bytes (a blob) instead
        text.encode("utf-8")
        value: str | bytes = text
    except UnicodeEncodeError:
        value = text.encode("utf-8", "surrogatepass")
    conn = sqlite3.connect(path)
    conn.execute("INSERT OR REPLACE INTO trials VALUES ('t', 's', 'e', 'a', 'c', 0, 0, 'finished', 'completed', 1, "
                 "'{}', ?)", (value,))
    conn.execute("INSERT OR REPLACE INTO steps VALUES ('t', 1, 1, 0, 0, 0, 0, ?)", (value,))
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
    raw = text.encode("utf-8", "surrogatepass")  # a lone surrogate as its bytes: the harness must not raise
    for kind in ("node", "begin", "step", "reply", "end", "done", "picture", "bag", "failed", text[:10]):
        for event in ((kind, payload), (kind, "k" * 64 + ":0", text), (kind, {text[:20]: raw})):
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


#: entry points whose bytes are not one text: each has a test of its own below, with its own generator
OWN_CASES = {"view request": "test_hostile_requests_to_view_serve",
             "guard events": "test_hostile_event_sequences_through_command_filter"}


def test_every_entry_point_has_a_fuzz_case():
    assert {entry.name for entry in ENTRY_POINTS} == set(TEXT_CASES) | set(FILE_CASES) | set(OWN_CASES)
    assert all(callable(globals().get(test)) for test in OWN_CASES.values())


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
    from safeembodai_core.runs.files import read_regular_file, read_run_text

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


# -- view request: raw requests to a real `view --serve` -------------------------------------------

SECRET = b"TOP-SECRET-OUTSIDE"
STATUS_LINE = re.compile(rb"HTTP/1\.0 [1-5]\d\d [^\r\n]*\r\n")
#: the most one request may take, answered, on a loaded machine (each is a local socket and one file)
REQUEST_S = 2.0
SITE_TARGETS = ["/", "/index.html", "/runs/page.html", "/pipe.html", "/out/secret", "/leak.html", "/runs/",
                "/rerun-viewer/runs/x.rrd", "*", "//out/secret", "/../outside/secret", "/%2e%2e/outside/secret",
                "/runs/%2e%2e/%2e%2e/outside/secret", "/%2E%2E%2Foutside%2Fsecret", "/runs/..%5c..%5csecret",
                "/index.html%00", "/%00", "/index.html%ff", "/out%2fsecret", "/.hidden", "/index.html?x=%00#y"]


@st.composite
def targets(draw, port: int) -> bytes:
    """A request target: a site path, an absolute-form or asterisk one, percent-encoded bytes, controls, long."""
    kind = draw(st.sampled_from(["site", "absolute", "encoded", "raw", "long"]))
    if kind == "site":
        return draw(st.sampled_from(SITE_TARGETS)).encode()
    if kind == "absolute":
        host = draw(st.sampled_from([f"127.0.0.1:{port}", "evil.example", "", "[::1]"]))
        return f"{draw(st.sampled_from(['http', 'https', 'file', 'HTTP']))}://{host}".encode() + \
            draw(st.sampled_from(SITE_TARGETS)).encode()
    if kind == "encoded":
        raw = draw(st.binary(max_size=40))
        return draw(st.sampled_from([b"/", b"/runs/", b"/out/"])) + "".join(f"%{b:02x}" for b in raw).encode()
    if kind == "raw":
        return draw(st.binary(max_size=60)).replace(b"\r", b"").replace(b"\n", b"")
    return b"/" + b"a" * draw(st.sampled_from([1_000, 65_000, 66_000, 300_000]))


@st.composite
def requests(draw, port: int) -> bytes:
    """One request: a method, target and version (any of them odd, missing or extra), then headers."""
    method = draw(st.sampled_from([b"GET", b"HEAD", b"POST", b"PUT", b"OPTIONS", b"CONNECT", b"get", b"G\x00T",
                                   b"do_GET", b"\x1b[31m", b"A" * 1000]))
    version = draw(st.sampled_from([b"HTTP/1.0", b"HTTP/1.1", b"HTTP/0.9", b"HTTP/2.0", b"HTTP/9.9", b"HTTP/1.1x",
                                    b"FOO/1.1", b"HTTP/01.1", b"HTTP/1.1 extra", b""]))
    line = b" ".join(part for part in (method, draw(targets(port)), version) if part)
    host = draw(st.sampled_from([f"127.0.0.1:{port}".encode(), f"localhost:{port}".encode(), b"evil.example",
                                 b"", None]))
    headers = [b"Host: " + host] if host is not None else []
    junk = st.binary(max_size=80).map(lambda b: b.replace(b"\r", b"").replace(b"\n", b""))
    headers += draw(st.lists(st.sampled_from([b"Origin: http://127.0.0.1:9090", b"Range: bytes=0-",
                                              b"Connection: keep-alive", b"Expect: 100-continue",
                                              b"Content-Length: 99999999", b"Transfer-Encoding: chunked",
                                              b"X-Long: " + b"x" * 70_000, b" folded", b"no colon"]) | junk,
                             max_size=8))
    if draw(st.booleans()) and draw(st.booleans()):
        headers += [b"X-Many: 1"] * 120
    return line + b"\r\n" + b"".join(header + b"\r\n" for header in headers) + b"\r\n"


def answer_to(port: int, request: bytes) -> tuple[bytes, float]:
    """The server's answer to ``request`` (at most 256 kB of it) and the seconds it took to end."""
    started = time.monotonic()
    with socket.create_connection(("127.0.0.1", port), timeout=REQUEST_S * 5) as conn:
        def send() -> None:
            try:
                conn.sendall(request)
            except OSError:  # answered and closed before it read everything (414, 431)
                pass

        sender = threading.Thread(target=send, daemon=True)
        sender.start()
        answer = b""
        while len(answer) < 256 * 1024:
            try:
                chunk = conn.recv(65536)
            except ConnectionResetError:  # closed with our bytes unread: what came before is the answer
                break
            if not chunk:
                break
            answer += chunk
        sender.join(REQUEST_S)
    return answer, time.monotonic() - started


@pytest.mark.skipif(not hasattr(os, "mkfifo"), reason="no FIFOs here")
def test_hostile_requests_to_view_serve(tmp_path_factory):
    """Every answer starts with a status line, nothing outside the site is ever served (through a
    symlinked folder, a symlinked page, ``..`` in any encoding), a FIFO answers at once, the server keeps
    answering, and each request is answered within :data:`REQUEST_S`."""
    from safeembodai_core.view.serve import SiteServer

    root = tmp_path_factory.mktemp("view")
    site, outside = root / "site", root / "outside"
    (site / "runs").mkdir(parents=True)
    outside.mkdir()
    (outside / "secret").write_bytes(SECRET)
    (site / "index.html").write_text("<html>index</html>")
    (site / "runs" / "page.html").write_text("<html>page</html>")
    (site / "out").symlink_to(outside)
    (site / "leak.html").symlink_to(outside / "secret")
    (site / "runs" / "x.rrd").symlink_to(outside / "secret")
    os.mkfifo(site / "pipe.html")
    server = SiteServer(site, lambda: None, port=0, interval_s=3600).start()
    port = server.httpd.server_address[1]
    ordinary = b"GET /runs/page.html HTTP/1.1\r\nHost: 127.0.0.1:%d\r\n\r\n" % port

    @settings(FUZZ, max_examples=200)
    @given(request=requests(port))
    def run(request):
        answer, took = answer_to(port, request)
        assert SECRET not in answer, request[:200]
        assert took < REQUEST_S, (took, request[:200])
        first_line = request.split(b"\r\n", 1)[0]
        if first_line.strip():  # http.server answers a blank request line by closing: nothing to answer
            assert STATUS_LINE.match(answer), (request[:200], answer[:200])
        still, _ = answer_to(port, ordinary)
        assert still.startswith(b"HTTP/1.0 200 ") and b"<html>page</html>" in still

    try:
        run()
    finally:
        server.stop()


# -- guard events: CommandFilter's scans, poses and commands in any order ------------------------

#: a guard decision's bounds, whatever the input: bytes allocated at the peak (issue 52's 100 MB), and CPU
#: seconds as a blow-up detector at 5x issue 52's 50 ms (the project times nothing in tests: the worst inputs
#: found, returns inside the body, measured 38-45 ms on the 2-core machine; figures go to the closing note and
#: docs/evidence, not into a timed assert that load could flip)
DECISION_CPU_S = 0.250
DECISION_BYTES = 100 * 1024**2

junk = st.recursive(st.none() | st.booleans() | st.integers() | st.floats() | st.text(max_size=10) |
                    st.binary(max_size=10) | st.just(10**400) | st.just(-(2**1100)),
                    lambda inner: st.lists(inner, max_size=4) | st.tuples(inner, inner) |
                    st.dictionaries(st.text(max_size=6), inner, max_size=4), max_leaves=12)
#: a number past what the guard reads: huge, non-finite, a bool, text, bytes, null, a container
odd_number = st.sampled_from([10**30, -(10**30), 2**1100, 10**400, True, False, "1", b"1", None, 1e308, -1e308,
                              5e-324, math.nan, math.inf, -math.inf]) | junk
#: a number as a caller or the wire may give one: mostly ordinary, often at or past the limits
any_number = st.one_of(st.floats(-5, 5), st.floats(-5, 5), st.integers(-10, 10), odd_number)


def mostly(usual, rare, share: int = 7):
    """``usual`` ``share`` times in ten, else ``rare``: the hostile values, but enough ordinary ones to reach
    the guard's judging (a scan that reads, then a command within its timeout)."""
    return st.integers(0, 9).flatmap(lambda k: usual if k < share else rare)


#: a time: mostly a few near ones (commands then fall within a scan's timeout, in or out of order), else any
times = mostly(st.sampled_from([0.0, 0.01, 0.05, 0.1, 0.2, 0.3]), st.floats(-1, 3) | odd_number)


@st.composite
def scans(draw):
    """A LaserScan as rosbridge (a dict), a decoded message (attributes) or a tuple: mostly one that
    reads, with a beam count up to 20,000 and ranges of any kind, often with a field spoiled."""
    count = draw(st.sampled_from([1, 4, 360, 720, 7_200, 20_000]))
    increment = draw(st.sampled_from([2 * math.pi / count, math.radians(1.0), math.radians(0.25)]))
    fill = draw(st.sampled_from(["one", "mixed", "drawn"]))
    beam = st.floats(0, 10) | st.sampled_from([math.nan, math.inf, -math.inf, 0.0, 1e308, -1.0])
    if fill == "one":
        ranges: Any = [draw(beam)] * count
    elif fill == "mixed":
        pattern = draw(st.lists(beam | st.none(), min_size=1, max_size=20))
        ranges = (pattern * (count // len(pattern) + 1))[:count]
    else:
        ranges = draw(st.lists(beam | any_number, min_size=1, max_size=40))
    fields: dict[str, Any] = {"angle_min": draw(st.sampled_from([0.0, -math.pi])), "angle_increment": increment,
                              "range_min": 0.05, "range_max": draw(st.sampled_from([8.0, 100_000.0])),
                              "ranges": ranges}
    if draw(st.booleans()):
        fields["angle_max"] = fields["angle_min"] + (len(ranges) - 1) * increment
    if isinstance(ranges, list) and draw(st.booleans()):
        fields["ranges"] = draw(st.sampled_from([tuple, lambda r: np.array(r, dtype=object),
                                                 lambda r: np.array([v if isinstance(v, float) else 0.0 for v in r])]
                                                ))(ranges)
    spoil = draw(mostly(st.just("none"), st.sampled_from(["value", "extra", "missing", "form"]), 6))
    if spoil == "value":
        fields[draw(st.sampled_from(sorted(fields)))] = draw(any_number)
    elif spoil == "extra":
        fields[draw(st.sampled_from(["header", "intensities", "extra", "time_increment"]))] = draw(junk)
    elif spoil == "missing":
        del fields[draw(st.sampled_from(sorted(fields)))]
    form = draw(st.sampled_from(["dict", "attributes"] + ["tuple", "junk"] * (spoil == "form")))
    if form == "dict":
        return fields
    if form == "attributes":
        return SimpleNamespace(**fields)
    if form == "tuple":
        return tuple(fields.values())
    return draw(junk)


@st.composite
def commands(draw):
    """A velocity command: a Twist, a tuple, a rosbridge dict, a decoded message or junk, numbers anywhere."""
    from safeembodai_core.ros import Twist

    speed = mostly(st.floats(-1, 1) | st.sampled_from([0.0, 0.3, 2.0, 100.0, 1e10, -1e30]), any_number, 8)
    x, z, y = draw(speed), draw(speed), draw(mostly(st.just(0.0), any_number, 8))
    form = draw(mostly(st.sampled_from(["twist", "tuple", "dict"]),
                       st.sampled_from(["stamped", "attributes", "junk"])))
    if form == "twist":
        try:
            return Twist(x, z, y)
        except (TypeError, ValueError):
            return Twist(0.3, 0.0)
    if form == "tuple":
        return draw(st.sampled_from([(x, z), (x, z, y), (x,), (x, z, y, 0.0)]))
    message = {"linear": {"x": x, "y": y, "z": 0.0}, "angular": {"x": 0.0, "y": 0.0, "z": z}}
    if form == "dict":
        return message
    if form == "stamped":
        return {"header": draw(junk), "twist": message}
    if form == "attributes":
        return SimpleNamespace(linear=SimpleNamespace(x=x, y=y, z=0.0),
                               angular=SimpleNamespace(x=0.0, y=0.0, z=z))
    return draw(junk)


poses = mostly(st.tuples(st.floats(-500, 500), st.floats(-500, 500), st.floats(-360, 360)),
               st.tuples(any_number, any_number, any_number) | st.lists(any_number, max_size=4) | junk |
               st.sampled_from([(1e300, -1e300, 1e300), "1,2,3", b"123", {1, 2, 3}]), 6)
events = st.lists(st.tuples(st.just("scan"), scans(), times) | st.tuples(st.just("pose"), poses, times) |
                  st.tuples(st.just("command"), commands(), times), min_size=1, max_size=12)


def bounded(call, *args):
    """``call(*args)``, the CPU seconds it took and what it raised; the allocation peak is measured on a
    twin filter (tracemalloc slows what it traces, so CPU is timed untraced). The cyclic collector is off
    while timed: a collection of hypothesis's own objects landing in one unread command cost it 93 ms (the
    traced twin runs with it on)."""
    gc.disable()
    started = time.process_time()
    try:
        return call(*args), time.process_time() - started, None
    except Exception as error:  # noqa: BLE001 -- which exception it was is the property checked
        return None, time.process_time() - started, error
    finally:
        gc.enable()


def test_hostile_event_sequences_through_command_filter():
    """Scans, poses and commands in any order, at any times, of any type: ``on_command`` returns a
    Decision (a stop when it cannot read or judge; a time that is no finite number is the caller's
    clock, a ValueError), ``on_scan`` and ``on_pose`` refuse with ValueError only, and every call stays
    within :data:`DECISION_CPU_S` of CPU and :data:`DECISION_BYTES` allocated."""
    from safeembodai_core import Guard
    from safeembodai_core.ros import CommandFilter, Decision
    from safeembodai_core.guard.command_filter import STOP
    from safeembodai_core.ros.laser_scan import shown

    guard = Guard()

    @settings(FUZZ, max_examples=300)
    @given(sequence=events, mode=st.sampled_from(["limit", "refuse"]))
    def run(sequence, mode):
        timed, traced = CommandFilter(guard, mode=mode), CommandFilter(guard, mode=mode)
        for kind, value, time_s in sequence:
            method = {"scan": "on_scan", "pose": "on_pose", "command": "on_command"}[kind]
            out, cpu_s, error = bounded(getattr(timed, method), value, time_s)
            tracemalloc.start()
            try:
                bounded(getattr(traced, method), value, time_s)
                _, peak = tracemalloc.get_traced_memory()
            finally:
                tracemalloc.stop()
            where = f"{method}({shown(value)}, {shown(time_s)})"
            assert cpu_s <= DECISION_CPU_S, f"{where} took {cpu_s * 1000:.1f} ms of CPU"
            assert peak <= DECISION_BYTES, f"{where} allocated {peak / 1024**2:.0f} MB"
            if error is not None:
                assert isinstance(error, ValueError), f"{where} raised {error!r}"
                assert kind != "command" or "time_s" in str(error), f"{where} raised {error!r}"
                continue
            if kind == "command":
                assert isinstance(out, Decision), where
                assert out.action in ("forward", "limit", "stop") and (out.action != "stop" or out.twist == STOP)
                if out.action == "stop":
                    assert out.reasons, where
                assert math.isfinite(out.twist.linear_x) and math.isfinite(out.twist.angular_z), where

    run()


@pytest.mark.parametrize("pattern, beams, increment, command", [
    ([0.06, 1e308], 20_000, math.radians(0.25), (100.0, 100.0)),  # a scan wrapping 14 turns, every other beam at 6 cm
    ([5.0, 0.06], 7_200, math.radians(0.05), (1.0, 0.0)),  # the finest scan read, every other beam inside the body
], ids=["20000-beams-wrapping", "7200-beams"])
def test_returns_inside_the_body_are_judged_within_the_bound(pattern, beams, increment, command):
    """What the fuzzing above found nearest the bound, kept as cases of their own: returns inside the body at
    the start (37-60 ms of CPU while sweep.deeper_times judged them 64 points at a time; its chunk now grows
    as the footprint's vertices allow)."""
    from safeembodai_core import Guard
    from safeembodai_core.ros import CommandFilter

    node = CommandFilter(Guard())
    node.on_scan({"angle_min": 0.0, "angle_increment": increment, "range_min": 0.05, "range_max": 8.0,
                  "ranges": (pattern * beams)[:beams]}, 0.0)
    spent = []
    for _ in range(3):
        started = time.process_time()
        decision = node.on_command(command, 0.1)
        spent.append(time.process_time() - started)
    assert decision.action == "stop"
    assert min(spent) <= DECISION_CPU_S, f"{min(spent) * 1000:.1f} ms of CPU"
