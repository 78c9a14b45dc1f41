"""Read a scenario file, apply ``--set`` overrides, validate, and check every component.

Errors name the file, the line and the dotted key (``mo.yaml:14: arms.safeembodai.failure_threshold:
Input should be greater than or equal to 0``); a key set with ``--set`` is named as such. Every problem
is reported at once, in file order: schema errors together with the options of every component that
could be read, and a misspelled key gets the closest known one ("did you mean 'trials'?"). The file and
every ``--set`` value are read within the bounds of :mod:`.limits`. A ``profile`` is applied by the
model (:mod:`.profiles`); each key the scenario sets otherwise is logged here as a warning.
"""

from __future__ import annotations

import difflib
import types
import typing
from pathlib import Path
from typing import Any, Iterable

import yaml
from pydantic import BaseModel, ValidationError

from ..errors import ComponentError, SafeEmbodAIError, ScenarioError
from ..logs import get_logger
from ..plugin.registry import ComponentOptionsError, ComponentRegistry
from ..plugin.refs import ComponentRef
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


#: The keys of a component reference (``ComponentRef``): a component written as its name alone takes them.
COMPONENT_KEYS = ("use", "options", "label")


def _default_component(field: str) -> Any:
    """The component a scenario gets for ``field`` when it names none (``perception: images``), as
    ``{use: name}``; ``{}`` for a field that is no component."""
    info = Scenario.model_fields.get(field)
    default: Any = info.get_default(call_default_factory=True) if info is not None else None
    return {"use": default.use} if hasattr(default, "use") else {}


def _apply_override(data: dict[str, Any], assignment: str) -> tuple[str, ...]:
    if "=" not in assignment:
        raise ScenarioError(f"--set {assignment!r}: expected dotted.key=value")
    key, _, raw = assignment.partition("=")
    parts = tuple(p for p in key.strip().split("."))
    if not key.strip() or any(not p for p in parts):
        raise ScenarioError(f"--set {assignment!r}: "
                            "the key must be dotted names like arms.safeembodai.failure_threshold")
    if len(parts) >= MAX_DEPTH:
        raise ScenarioError(f"--set {key[:80]}...: more than {MAX_DEPTH - 1} dotted names (the limit for a scenario)")
    value = load_value(raw, f"--set {key}", len(parts)) if raw.strip() else ""
    target: Any = data
    for depth, part in enumerate(parts[:-1]):
        if isinstance(target, list):
            if not part.isdigit() or int(part) >= len(target):
                raise ScenarioError(f"--set {key}: {_dotted(parts[:depth + 1])} is not an index of the list")
            slot: Any = int(part)
        elif isinstance(target, dict):
            if part not in target and depth == 0 and parts[1] in COMPONENT_KEYS:
                target[part] = _default_component(part)  # perception.options.x on a scenario silent on it
            target.setdefault(part, {})
            slot = part
        else:
            raise ScenarioError(f"--set {key}: {_dotted(parts[:depth])} is not a mapping or list")
        if isinstance(target[slot], str) and parts[depth + 1] in COMPONENT_KEYS:
            # a component named alone (``backend: mock``) is the mapping {use: mock}: its options can be set
            target[slot] = {"use": target[slot]}
        target = target[slot]
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

    problems: list[tuple[tuple[Any, ...], str]] = []
    scenario = None
    if data.get("profile") is not None:
        try:  # a file names its profile; the {name, overridden} record is what scenario.json holds
            if not isinstance(data["profile"], str):
                raise ValueError(f"give a profile's name, not a {type(data['profile']).__name__}")
            profile_name(data["profile"])
        except ValueError as error:
            problems.append((("profile",), f"{locate(('profile',))}: profile: {error}"))
            data = {key: value for key, value in data.items() if key != "profile"}  # the rest is checked as written
    try:
        validated = Scenario.model_validate(data)
        scenario = None if problems else validated
    except ValidationError as error:
        for item in error.errors():
            loc = tuple(p for p in item["loc"]
                        if not (isinstance(p, str) and p in ("function-before", "function-after")))
            message = item["msg"] + (_did_you_mean(Scenario, loc) if item["type"] == "extra_forbidden" else "")
            problems.append((loc, f"{locate(loc)}: {_dotted(loc) or '(top level)'}: {message}"))
    if registry is not None:
        if scenario is not None:
            check_components(scenario, registry, locate)
        else:  # the components that could be read are checked too: every problem at once
            wrong = [loc for loc, _ in problems]
            refs = [(kind, loc, ref) for kind, loc, ref in _raw_refs(data)
                    if not any(loc[:len(bad)] == bad or bad[:len(loc)] == loc for bad in wrong)]
            problems.extend(_component_problems(refs, registry, locate))
    if problems:  # in file order, then the --set keys (a stable sort keeps the rest as found)
        problems.sort(key=lambda problem: (1, 0) if locate(problem[0]).startswith("--set")
                      else (0, _line_of(root, problem[0]) or 0))
        raise ScenarioError("invalid scenario:\n  " + "\n  ".join(message for _, message in problems))
    assert scenario is not None
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


def _raw_refs(data: dict[str, Any]) -> list[tuple[str, tuple[Any, ...], ComponentRef]]:
    """The component references of a scenario that did not validate, as far as they can be read."""
    found: list[tuple[str, tuple[Any, ...], Any]] = []
    environments = data.get("environments")
    for index, raw in enumerate(environments if isinstance(environments, list) else []):
        found.append(("environment", ("environments", index), raw))
    for kind, key in (("llm_backend", "backend"), ("perception", "perception"), ("prompt_builder", "prompt_builder"),
                      ("state_store", "state")):
        if data.get(key) is not None:
            found.append((kind, (key,), data[key]))
    for section, key, kind in (("arms", "validators", "validator"), ("conditions", "attackers", "attacker")):
        groups = data.get(section)
        for name, group in (groups.items() if isinstance(groups, dict) else ()):
            refs = group.get(key) if isinstance(group, dict) else None
            for index, raw in enumerate(refs if isinstance(refs, list) else []):
                found.append((kind, (section, name, key, index), raw))
    readable = []
    for kind, loc, raw in found:
        try:
            readable.append((kind, loc, ComponentRef.model_validate(raw)))
        except ValidationError:
            continue
    return readable


def _component_problems(refs: Iterable[tuple[str, tuple[Any, ...], ComponentRef]], registry: ComponentRegistry,
                        locate: Any) -> list[tuple[tuple[Any, ...], str]]:
    """(where, message) for every reference to an unknown component or with options that do not validate."""
    problems = []
    for kind, loc, ref in refs:
        try:
            info = registry.get(kind, ref.use)
            registry.validate_options(kind, ref.use, ref.options)
        except ComponentOptionsError as error:
            for sub, msg in error.errors:
                full = loc + ("options",) + sub
                if msg == "Extra inputs are not permitted":
                    msg += _did_you_mean(info.options, sub)
                problems.append((full, f"{locate(full)}: {_dotted(full)}: {msg} "
                                       f"({kind} {ref.use!r} from plugin {info.plugin!r})"))
        except ComponentError as error:
            problems.append((loc + ("use",), f"{locate(loc + ('use',))}: {_dotted(loc)}: {error}"))
    return problems


def _did_you_mean(model: type[BaseModel], loc: tuple[Any, ...]) -> str:
    """"; did you mean 'trials'?" for a key at ``loc`` that ``model`` does not know (or "")."""
    known = _keys_at(model, loc[:-1])
    close = difflib.get_close_matches(str(loc[-1]), known, n=1) if loc else []
    return f"; did you mean {close[0]!r}?" if close else ""


def _keys_at(annotation: Any, loc: tuple[Any, ...]) -> list[str]:
    """The keys a mapping at ``loc`` inside ``annotation`` (a model) may hold; [] where it cannot tell."""
    for part in (*loc, None):
        while typing.get_origin(annotation) in (typing.Union, types.UnionType):
            members = [a for a in typing.get_args(annotation) if a is not type(None)]
            annotation = next((a for a in members if typing.get_origin(a) in (dict, list)
                               or (isinstance(a, type) and issubclass(a, BaseModel))), None)
        if isinstance(annotation, type) and issubclass(annotation, BaseModel):
            if part is None:
                return list(annotation.model_fields)
            field = annotation.model_fields.get(str(part))
            annotation = field.annotation if field is not None else None
        elif typing.get_origin(annotation) in (dict, list) and part is not None:
            annotation = typing.get_args(annotation)[-1] if typing.get_args(annotation) else None
        else:
            return []
    return []


def check_components(scenario: Scenario, registry: ComponentRegistry, locate: Any = None) -> None:
    """Every referenced component exists and its options validate; all problems reported at once."""
    locate = locate or (lambda loc: "<scenario>")
    problems = [message for _, message in _component_problems(_refs(scenario), registry, locate)]
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
        builder = registry.build_ref("prompt_builder", ref)
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


def load_scenario(path: str | Path, overrides: Iterable[str] = (),
                  registry: ComponentRegistry | None = None) -> Scenario:
    """Read and validate the scenario file at ``path`` (a regular file within :mod:`.limits`)."""
    path = Path(path)
    return parse_scenario(read_scenario_text(path), str(path), overrides, registry)
