"""Read a scenario file, apply ``--set`` overrides, validate, and check every component.

Errors name the file, the line and the dotted key (``mo.yaml:14: arms.safeembodai.failure_threshold:
Input should be greater than or equal to 0``); a key set with ``--set`` is named as such. The file and
every ``--set`` value are read within the bounds of :mod:`.limits`. A ``profile`` is applied by the
model (:mod:`.profiles`); each key the scenario sets otherwise is logged here as a warning.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any, Iterable

import yaml
from pydantic import ValidationError

from ..errors import ComponentError, SafeEmbodAIError, ScenarioError
from ..logs import get_logger
from ..registry import ComponentOptionsError, ComponentRegistry
from ..refs import ComponentRef
from .limits import MAX_DEPTH, BoundedLoader, load_value, read_scenario_text, yaml_error
from .model import Scenario
from .profiles import profile_name

log = get_logger(__name__)


def _dotted(loc: Iterable[Any]) -> str:
    return ".".join(str(p) for p in loc)


def _line_of(node: yaml.Node | None, loc: Iterable[Any]) -> int | None:
    """1-based line of the deepest YAML node along ``loc``.

    The last matching key wins: after ``<<`` merges are applied, a mapping's own keys follow (and
    override) the merged ones.
    """
    if node is None:
        return None
    line = node.start_mark.line + 1
    for part in loc:
        child = None
        if isinstance(node, yaml.MappingNode):
            for key, value in node.value:
                if isinstance(key, yaml.ScalarNode) and key.value == str(part):
                    child = value
                    line = key.start_mark.line + 1
        elif isinstance(node, yaml.SequenceNode) and isinstance(part, int) and 0 <= part < len(node.value):
            child = node.value[part]
            line = child.start_mark.line + 1
        if child is None:
            break
        node = child
    return line


def _check_duplicate_keys(node: yaml.Node | None, source: str, path: tuple[Any, ...] = (),
                          checked: set[int] | None = None) -> None:
    """Refuse a key written twice in one mapping; a node reached again through an alias is checked once."""
    checked = set() if checked is None else checked
    if id(node) in checked or isinstance(node, yaml.ScalarNode):
        return
    checked.add(id(node))
    if isinstance(node, yaml.MappingNode):
        seen: dict[str, int] = {}
        for key, value in node.value:
            if not isinstance(key, yaml.ScalarNode):  # refused as unhashable when constructed
                continue
            name = key.value
            if name in seen:
                raise ScenarioError(
                    f"{source}:{key.start_mark.line + 1}: {_dotted(path + (name,))}: key repeated "
                    f"(first on line {seen[name]})"
                )
            seen[name] = key.start_mark.line + 1
            _check_duplicate_keys(value, source, path + (name,), checked)
    elif isinstance(node, yaml.SequenceNode):
        for index, item in enumerate(node.value):
            _check_duplicate_keys(item, source, path + (index,), checked)


def _apply_override(data: dict[str, Any], assignment: str) -> tuple[str, ...]:
    if "=" not in assignment:
        raise ScenarioError(f"--set {assignment!r}: expected dotted.key=value")
    key, _, raw = assignment.partition("=")
    parts = tuple(p for p in key.strip().split("."))
    if not key.strip() or any(not p for p in parts):
        raise ScenarioError(f"--set {assignment!r}: the key must be dotted names like arms.safeembodai.failure_threshold")
    if len(parts) >= MAX_DEPTH:
        raise ScenarioError(f"--set {key[:80]}...: more than {MAX_DEPTH - 1} dotted names (the limit for a scenario)")
    value = load_value(raw, f"--set {key}", len(parts)) if raw.strip() else ""
    target: Any = data
    for depth, part in enumerate(parts[:-1]):
        if isinstance(target, list):
            if not part.isdigit() or int(part) >= len(target):
                raise ScenarioError(f"--set {key}: {_dotted(parts[:depth + 1])} is not an index of the list")
            target = target[int(part)]
        elif isinstance(target, dict):
            target = target.setdefault(part, {})
        else:
            raise ScenarioError(f"--set {key}: {_dotted(parts[:depth])} is not a mapping or list")
    last = parts[-1]
    if isinstance(target, list) and last.isdigit() and int(last) < len(target):
        target[int(last)] = value
    elif isinstance(target, dict):
        target[last] = value
    else:
        raise ScenarioError(f"--set {key}: {_dotted(parts[:-1])} is not a mapping")
    return parts


def parse_scenario(
    text: str,
    source: str = "<scenario>",
    overrides: Iterable[str] = (),
    registry: ComponentRegistry | None = None,
) -> Scenario:
    """Validate scenario ``text``; with ``registry``, also check every component and its options."""
    loader = None
    try:
        loader = BoundedLoader(text, source)  # reading starts here: it refuses unprintable characters
        root = loader.get_single_node()
        _check_duplicate_keys(root, source)  # before constructing: applying ``<<`` merges rewrites the nodes
        data = loader.construct_document(root) if root is not None else {}
    except yaml.YAMLError as error:
        raise yaml_error(error, source, text) from None
    finally:
        if loader is not None:
            loader.dispose()
    if data is None:
        data = {}
    if not isinstance(data, dict):
        raise ScenarioError(f"{source}: a scenario must be a YAML mapping, got {type(data).__name__}")
    overridden = [_apply_override(data, item) for item in overrides]

    def locate(loc: tuple[Any, ...]) -> str:
        for parts in overridden:
            if tuple(str(p) for p in loc[: len(parts)]) == parts or tuple(str(p) for p in loc) == parts[: len(loc)]:
                return f"--set {_dotted(parts)}"
        line = _line_of(root, loc)
        return f"{source}:{line}" if line else source

    if data.get("profile") is not None:
        try:  # a file names its profile; the {name, overridden} record is what scenario.json holds
            if not isinstance(data["profile"], str):
                raise ValueError(f"give a profile's name, not a {type(data['profile']).__name__}")
            profile_name(data["profile"])
        except ValueError as error:
            raise ScenarioError(f"invalid scenario:\n  {locate(('profile',))}: profile: {error}") from None
    try:
        scenario = Scenario.model_validate(data)
    except ValidationError as error:
        lines = []
        for item in error.errors():
            loc = tuple(p for p in item["loc"] if not (isinstance(p, str) and p in ("function-before", "function-after")))
            lines.append(f"{locate(loc)}: {_dotted(loc) or '(top level)'}: {item['msg']}")
        raise ScenarioError("invalid scenario:\n  " + "\n  ".join(lines)) from None
    if registry is not None:
        check_components(scenario, registry, locate)
    if scenario.profile is not None:
        for key, values in scenario.profile.overridden.items():
            log.warning("scenario.profile_overridden", scenario=source, profile=scenario.profile.name, key=key,
                        profile_value=values["profile"], value=values["scenario"], at=locate(tuple(key.split("."))))
    return scenario


def _refs(scenario: Scenario) -> list[tuple[str, tuple[Any, ...], ComponentRef]]:
    refs: list[tuple[str, tuple[Any, ...], ComponentRef]] = []
    for index, ref in enumerate(scenario.environments):
        refs.append(("environment", ("environments", index), ref))
    refs.append(("llm_backend", ("backend",), scenario.backend))
    refs.append(("perception", ("perception",), scenario.perception))
    refs.append(("prompt_builder", ("prompt_builder",), scenario.prompt_builder))
    refs.append(("state_store", ("state",), scenario.state))
    for arm, defences in scenario.arms.items():
        for index, ref in enumerate(defences.validators):
            refs.append(("validator", ("arms", arm, "validators", index), ref))
    for name, condition in scenario.conditions.items():
        for index, ref in enumerate(condition.attackers):
            refs.append(("attacker", ("conditions", name, "attackers", index), ref))
    return refs


def check_components(scenario: Scenario, registry: ComponentRegistry, locate: Any = None) -> None:
    """Every referenced component exists and its options validate; all problems reported at once."""
    locate = locate or (lambda loc: "<scenario>")
    problems = []
    for kind, loc, ref in _refs(scenario):
        try:
            info = registry.get(kind, ref.use)
            registry.validate_options(kind, ref.use, ref.options)
        except ComponentOptionsError as error:
            for sub, msg in error.errors:
                full = loc + ("options",) + sub
                problems.append(f"{locate(full)}: {_dotted(full)}: {msg} ({kind} {ref.use!r} from plugin {info.plugin!r})")
        except ComponentError as error:
            problems.append(f"{locate(loc + ('use',))}: {_dotted(loc)}: {error}")
    if not problems:
        problems.extend(_check_prefix_variants(scenario, registry, locate))
    if problems:
        raise ScenarioError("invalid scenario:\n  " + "\n  ".join(problems))


def _check_prefix_variants(scenario: Scenario, registry: ComponentRegistry, locate: Any) -> list[str]:
    """Arms may only name security-prefix variants the prompt builder has (when it can tell)."""
    wanted = {arm: d.prefix_variant for arm, d in scenario.arms.items() if d.prefix_variant is not None}
    if not wanted:
        return []
    ref = scenario.prompt_builder
    try:
        builder = registry.build("prompt_builder", ref.use, ref.options)
    except SafeEmbodAIError as error:
        return [f"{locate(('prompt_builder',))}: prompt_builder: {error}"]
    known = builder.security_prefix_variants() if hasattr(builder, "security_prefix_variants") else None
    if known is None:
        return []
    return [
        f"{locate(('arms', arm, 'security_prefix'))}: arms.{arm}.security_prefix: no security-prefix variant "
        f"{variant!r} in prompt builder {ref.use!r}; known: {', '.join(known)}"
        for arm, variant in wanted.items() if variant not in known
    ]


def load_scenario(path: str | Path, overrides: Iterable[str] = (), registry: ComponentRegistry | None = None) -> Scenario:
    """Read and validate the scenario file at ``path`` (a regular file within :mod:`.limits`)."""
    path = Path(path)
    return parse_scenario(read_scenario_text(path), str(path), overrides, registry)
