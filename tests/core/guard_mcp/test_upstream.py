"""The upstream's session: its results checked against each tool's output schema as the SDK checks them, by a
validator built once per tool."""

from __future__ import annotations

import asyncio

import pytest

pytest.importorskip("mcp", reason="guard-mcp needs the MCP SDK: pip install -e '.[mcp]'")
import anyio  # noqa: E402
from mcp import types  # noqa: E402

from safeembodai_core.guard_mcp.upstream import UpstreamSession  # noqa: E402

SCHEMAS = {"published": {"type": "object", "properties": {"published_count": {"type": "integer"}},
                         "required": ["published_count"]},
           "free": {"additionalProperties": True, "type": "object"}, "none": None,
           "broken": {"type": "object", "properties": {"x": {"type": 7}}}}


def checked(tool, structured):
    async def run():
        sent, read = anyio.create_memory_object_stream(1)
        written, _ = anyio.create_memory_object_stream(1)
        session = UpstreamSession(read, written)
        session._tool_output_schemas = dict(SCHEMAS)
        result = types.CallToolResult(content=[], structuredContent=structured)
        await session._validate_tool_result(tool, result)
        await session._validate_tool_result(tool, result)  # the validator built once, used again
        return session.__dict__.get("_validators", {})

    return asyncio.run(run())


def test_a_result_its_schema_admits_passes_and_its_validator_is_kept():
    assert set(checked("published", {"published_count": 3})) == {"published"}
    assert checked("free", {"anything": [1]}) and checked("none", None) == {}


@pytest.mark.parametrize("tool, structured, error", [
    ("published", {"published_count": "3"}, "Invalid structured content returned by tool published"),
    ("published", {}, "'published_count' is a required property"),
    ("free", None, "did not return structured content"),
    ("broken", {"x": 1}, "Invalid schema for tool broken")])
def test_a_result_its_schema_refuses_fails_as_the_sdks_check_fails(tool, structured, error):
    with pytest.raises(RuntimeError, match=error):
        checked(tool, structured)
