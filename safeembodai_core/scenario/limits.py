"""Bounds on a scenario file and on the work of loading it.

A scenario is a few KB of YAML (the shipped ones have under 100 nodes, 7 levels deep), but the
loader reads whatever path it is given. So that no file can hang or crash it:

* only a regular file is read (never a FIFO, device, socket or directory; ``/dev/zero`` and a pipe
  nobody writes to are refused without reading), and at most :data:`MAX_BYTES` of it;
* composing the YAML counts nodes with every alias expanded, as everything downstream (the
  duplicate-key check, pydantic, ``scenario.json``) sees them, so an alias bomb is refused after
  composing only as many nodes as it has before its expansion passes :data:`MAX_NODES`; an alias
  inside the node it names (``&a [*a]``) is refused outright;
* so does the text of its scalars (:data:`MAX_TEXT` characters): one long string aliased
  thousands of times would otherwise make a ``scenario.json`` of hundreds of MB;
* nesting, aliases expanded, stops at :data:`MAX_DEPTH` levels, far below Python's recursion limit;
* integers have at most :data:`MAX_INT_DIGITS` digits, so every value can be written back as JSON.

Every refusal is a :class:`ScenarioError` naming the file, the line where known, and the limit.
"""

from __future__ import annotations

import os
import stat
from pathlib import Path
from typing import TYPE_CHECKING, Any

import yaml
from yaml.events import AliasEvent

from ..errors import ScenarioError

if TYPE_CHECKING:
    from yaml._yaml import Mark as _LibyamlMark  # libyaml's marks, which the stubs allow on an event

MAX_BYTES = 1024 * 1024
MAX_NODES = 100_000
MAX_TEXT = 4 * MAX_BYTES  # characters of scalar text, aliases expanded
MAX_DEPTH = 64
MAX_INT_DIGITS = 4300  # Python's own limit for int <-> str conversion

_INT_BOUND = 10**MAX_INT_DIGITS
_KINDS = ((stat.S_ISDIR, "a directory"), (stat.S_ISFIFO, "a FIFO (named pipe)"), (stat.S_ISCHR, "a character device"),
          (stat.S_ISBLK, "a block device"), (stat.S_ISSOCK, "a socket"))


def _check_regular(path: Path, info: os.stat_result) -> None:
    if not stat.S_ISREG(info.st_mode):
        kind = next((name for test, name in _KINDS if test(info.st_mode)), "not a regular file")
        raise ScenarioError(f"{path}: is {kind}; a scenario must be a regular file")
    if info.st_size > MAX_BYTES:
        raise ScenarioError(f"{path}: is {info.st_size} bytes; "
                            f"a scenario file may have at most {MAX_BYTES} bytes (1 MiB)")


def read_scenario_text(path: Path) -> str:
    """The text of the scenario file at ``path``: a regular file of at most :data:`MAX_BYTES`, in UTF-8.

    The file is checked before it is opened (opening a FIFO would wait for a writer, and opening a
    device can have effects of its own), opened without blocking, and checked again once open, in
    case it was replaced in between.
    """
    try:
        _check_regular(path, os.stat(path))
        flags = os.O_RDONLY | getattr(os, "O_NONBLOCK", 0) | getattr(os, "O_NOCTTY", 0) | getattr(os, "O_BINARY", 0)
        fd = os.open(path, flags)
        try:
            _check_regular(path, os.fstat(fd))
            chunks, size = [], 0
            while size <= MAX_BYTES:
                chunk = os.read(fd, MAX_BYTES + 1 - size)
                if not chunk:
                    break
                chunks.append(chunk)
                size += len(chunk)
        finally:
            os.close(fd)
    except FileNotFoundError:
        raise ScenarioError(f"{path}: no such scenario file") from None
    except OSError as error:
        raise ScenarioError(f"{path}: cannot read scenario: {error.strerror or error}") from None
    if size > MAX_BYTES:  # it grew after the size check
        raise ScenarioError(f"{path}: is more than {MAX_BYTES} bytes; "
                            f"a scenario file may have at most {MAX_BYTES} bytes (1 MiB)")
    try:
        return b"".join(chunks).decode("utf-8")
    except UnicodeDecodeError as error:
        raise ScenarioError(f"{path}: cannot read scenario: not UTF-8 ({error.reason} at byte {error.start})") from None


class BoundedLoader(yaml.SafeLoader):
    """A ``SafeLoader`` that refuses, while composing, a document over the node, depth or alias limits.

    Every node counts once for each place it appears once aliases are expanded; the expanded size,
    text and height of each anchored node are remembered, so an alias costs O(1) to check.
    """

    def __init__(self, text: str, source: str, depth: int = 0, with_lines: bool = True) -> None:
        super().__init__(text)
        self.source = source
        self.with_lines = with_lines
        self._nodes = 0
        self._text = 0
        self._depth = depth  # of the node being composed: the root is at depth + 1 (a --set value below its key)
        self._deepest = 0
        self._anchored: dict[int, tuple[int, int, int]] = {}  # id(node) -> (nodes, text, height), once complete

    def _refuse(self, mark: yaml.Mark | _LibyamlMark, problem: str) -> ScenarioError:
        return ScenarioError(f"{self.source}:{mark.line + 1}: {problem}" if self.with_lines
                             else f"{self.source}: {problem}")

    def _count(self, nodes: int, text: int, deepest: int, mark: yaml.Mark | _LibyamlMark, what: str) -> None:
        self._nodes += nodes
        self._text += text
        if self._nodes > MAX_NODES:
            raise self._refuse(mark, f"more than {MAX_NODES} YAML nodes{what} (the limit for a scenario)")
        if self._text > MAX_TEXT:
            raise self._refuse(mark, f"more than {MAX_TEXT} characters of text{what} (the limit for a scenario)")
        if deepest > MAX_DEPTH:
            raise self._refuse(mark, f"nested deeper than {MAX_DEPTH} levels{what} (the limit for a scenario)")
        self._deepest = max(self._deepest, deepest)

    def compose_node(self, parent: yaml.Node | None, index: Any) -> yaml.Node | None:
        event = self.peek_event()
        assert event.start_mark is not None  # the parser marks every event it makes
        if isinstance(event, AliasEvent):
            target = self.anchors.get(event.anchor)
            if target is not None:
                if id(target) not in self._anchored:
                    raise self._refuse(event.start_mark, f"alias *{event.anchor} is recursive "
                                                         f"(it refers to a node that contains it)")
                nodes, text, height = self._anchored[id(target)]
                self._count(nodes, text, self._depth + height, event.start_mark,
                            f" once alias *{event.anchor} is expanded")
            return super().compose_node(parent, index)
        self._depth += 1
        outer_deepest, self._deepest = self._deepest, self._depth
        nodes_before, text_before = self._nodes, self._text
        try:
            self._count(1, 0, self._depth, event.start_mark, "")
            node = super().compose_node(parent, index)
            if isinstance(node, yaml.ScalarNode):
                self._count(0, len(node.value), self._depth, event.start_mark, "")
            if event.anchor is not None:
                self._anchored[id(node)] = (self._nodes - nodes_before, self._text - text_before,
                                            self._deepest - self._depth + 1)
        finally:
            self._depth -= 1
            self._deepest = max(outer_deepest, self._deepest)
        return node

    def construct_object(self, node: yaml.Node, deep: bool = False) -> Any:
        try:
            return super().construct_object(node, deep)
        except (ValueError, OverflowError) as error:  # e.g. a date 2024-13-45
            raise yaml.constructor.ConstructorError(None, None, f"invalid {node.tag.rpartition(':')[2]}: {error}",
                                                    node.start_mark) from None

    def construct_yaml_int(self, node: yaml.ScalarNode) -> int:
        try:  # the length check first: base-60 integers (1:2:3) cost quadratic time in their length
            value = super().construct_yaml_int(node) if len(str(node.value)) <= 4 * MAX_INT_DIGITS else _INT_BOUND
        except ValueError:
            value = _INT_BOUND
        if abs(value) >= _INT_BOUND:
            raise yaml.constructor.ConstructorError(None, None, f"integer with more than {MAX_INT_DIGITS} digits",
                                                    node.start_mark)
        return value


BoundedLoader.add_constructor("tag:yaml.org,2002:int", BoundedLoader.construct_yaml_int)


def yaml_error(error: yaml.YAMLError, source: str, text: str, with_lines: bool = True) -> ScenarioError:
    """``source:line: not valid YAML: problem`` on one line."""
    line = None
    if isinstance(error, yaml.reader.ReaderError):
        line = text.count("\n", 0, error.position) + 1
        problem = error.reason + (f" (character #x{error.character:04x})" if isinstance(error.character, int) else "")
    else:
        mark = getattr(error, "problem_mark", None) or getattr(error, "context_mark", None)
        line = mark.line + 1 if mark is not None else None
        problem = getattr(error, "problem", None) or getattr(error, "context", None) or error
    where = f"{source}:{line}" if line is not None and with_lines else source
    return ScenarioError(f"{where}: not valid YAML: {problem}")


def load_value(text: str, source: str, depth: int = 0) -> Any:
    """One YAML value (a ``--set`` value) placed ``depth`` levels down, within the limits of a scenario file."""
    loader = None
    try:
        loader = BoundedLoader(text, source, depth, with_lines=False)
        return loader.get_single_data()
    except yaml.YAMLError as error:
        raise yaml_error(error, source, text, with_lines=False) from None
    finally:
        if loader is not None:
            loader.dispose()
