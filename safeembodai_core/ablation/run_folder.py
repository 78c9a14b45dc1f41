"""A run folder: the scenario it ran (fingerprinted), its results store, pictures and reports.

``scenario.json`` holds the validated scenario and its SHA-256 fingerprint. Resuming compares the
scenario given now with it and refuses any difference, naming the keys that changed, because
mixing trials of two different scenarios would make every metric meaningless.
"""

from __future__ import annotations

import hashlib
import json
import time
from pathlib import Path
from typing import Any

from ..errors import SafeEmbodAIError
from ..scenario import Scenario

SCENARIO_FILE = "scenario.json"


def fingerprint(scenario: Scenario) -> str:
    canonical = json.dumps(scenario.model_dump(mode="json"), sort_keys=True, separators=(",", ":"))
    return hashlib.sha256(canonical.encode()).hexdigest()


def _changed_keys(old: Any, new: Any, prefix: str = "") -> list[str]:
    if isinstance(old, dict) and isinstance(new, dict):
        keys = sorted(set(old) | set(new))
        return [k for key in keys for k in _changed_keys(old.get(key), new.get(key), f"{prefix}{key}.")]
    return [] if old == new else [prefix.rstrip(".") or "(root)"]


class RunFolder:
    """The folder of one ablation run."""

    def __init__(self, path: str | Path) -> None:
        self.path = Path(path)

    @classmethod
    def create(cls, root: str | Path, scenario: Scenario) -> "RunFolder":
        stamp = time.strftime("%Y%m%d-%H%M%S")
        path = Path(root) / f"{scenario.name}-{stamp}"
        suffix = 1
        while path.exists():
            suffix += 1
            path = Path(root) / f"{scenario.name}-{stamp}-{suffix}"
        return cls(path)

    def start(self, scenario: Scenario) -> None:
        """Create the folder and record the scenario (new runs only)."""
        try:
            self.path.mkdir(parents=True, exist_ok=True)
            target = self.path / SCENARIO_FILE
            if target.exists():
                raise SafeEmbodAIError(f"{self.path} already holds a run; use --resume {self.path} to finish it")
            record = {"fingerprint": fingerprint(scenario), "scenario": scenario.model_dump(mode="json")}
            target.write_text(json.dumps(record, indent=2), encoding="utf-8")
        except OSError as error:
            raise SafeEmbodAIError(f"cannot write the run folder {self.path}: {error}") from None

    def recorded_scenario(self) -> dict[str, Any]:
        target = self.path / SCENARIO_FILE
        try:
            return json.loads(target.read_text(encoding="utf-8"))
        except FileNotFoundError:
            raise SafeEmbodAIError(f"{self.path} is not a run folder (no {SCENARIO_FILE})") from None
        except (OSError, json.JSONDecodeError) as error:
            raise SafeEmbodAIError(f"{target} is unreadable: {error}") from None

    def check_same(self, scenario: Scenario) -> None:
        """Refuse to resume with a scenario that differs from the one the run started with."""
        recorded = self.recorded_scenario()
        if recorded.get("fingerprint") == fingerprint(scenario):
            return
        changed = _changed_keys(recorded.get("scenario", {}), scenario.model_dump(mode="json"))
        raise SafeEmbodAIError(
            f"the scenario differs from the one {self.path} was started with (changed: {', '.join(changed) or 'unknown'}); "
            "resume with the same scenario and overrides, or start a new run"
        )

    def scenario(self) -> Scenario:
        return Scenario.model_validate(self.recorded_scenario()["scenario"])
