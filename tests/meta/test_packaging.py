"""The wheel works outside the source tree, and a third-party plugin package is found by entry point.

Slow: builds the project's wheel, installs it into a fresh virtual environment (third-party
dependencies are borrowed from the running environment through a .pth file, so nothing is
downloaded), then installs the example plugin package from docs/examples/ into it.
"""

from __future__ import annotations

import json
import os
import shutil
import site
import subprocess
import sys
import venv
from pathlib import Path

import pytest

pytestmark = pytest.mark.slow

REPO = Path(__file__).resolve().parents[2]

_ANYWHERE = shutil.ignore_patterns(".git", "build", "dist", "__pycache__", "*.egg-info", ".venv", ".pytest_cache",
                                   ".hypothesis", "*.sqlite*")


def IGNORE(folder: str, names: list[str]) -> set[str]:
    """What the copy of the repository leaves out: build and cache folders anywhere, and the run folders of
    ``runs/`` at its top only (``safeembodai_core/runs`` is a package)."""
    left_out = set(_ANYWHERE(folder, names))
    if Path(folder).resolve() == REPO and "runs" in names:
        left_out.add("runs")
    return left_out


# The installed geofence, found by its entry point, guarding plans from a pose (docs/plugins.md).
GEOFENCE_CHECK = """
from safeembodai_core import Guard
from safeembodai_core.testing import straight, turn

guard = Guard(rules=[{"use": "geofence", "options": {"x_min_mm": 0, "x_max_mm": 3000, \
"y_min_mm": 0, "y_max_mm": 2000}}])
print("inside:", guard.check([turn(45), straight(390)], pose=(1000, 1000, 0)).valid)
leaving = guard.check([turn(45), straight(390)], pose=(2700, 1700, 0))
print("leaving:", leaving.valid)
print(leaving.reasons[0])
"""


def _run(*args, cwd=None, env=None, check=True):
    completed = subprocess.run([str(a) for a in args], capture_output=True, text=True, cwd=cwd, env=env, timeout=600)
    if check and completed.returncode != 0:
        raise AssertionError(f"{args} failed:\n{completed.stdout}\n{completed.stderr}")
    return completed


@pytest.fixture(scope="module")
def installed(tmp_path_factory, repo):
    root = tmp_path_factory.mktemp("pkg")
    source = root / "source"
    shutil.copytree(repo, source, ignore=IGNORE)
    built = _run(sys.executable, "-m", "pip", "wheel", "--no-deps", "--no-build-isolation", "-w", root / "wheels",
                 source)
    wheel = next((root / "wheels").glob("safeembodai-*.whl"))
    env_dir = root / "venv"
    venv.create(env_dir, with_pip=True)
    python = env_dir / "bin" / "python"
    purelib = Path(_run(python, "-c", "import sysconfig; print(sysconfig.get_paths()['purelib'])").stdout.strip())
    (purelib / "borrowed_deps.pth").write_text("\n".join(site.getsitepackages()) + "\n")
    _run(python, "-m", "pip", "install", "-q", "--no-deps", "--no-index", wheel)
    work = root / "elsewhere"
    work.mkdir()
    return python, work, built.stdout + built.stderr, wheel


BUILD_WARNINGS = ("SetuptoolsDeprecationWarning", "BuildBackendWarning", "is deprecated", "absent from the `packages`",
                  "Package would be ignored")


def test_the_wheel_builds_without_setuptools_warnings(installed):
    """A deprecation (``license`` as a table stops building after 2027-02-18) or an unlisted data folder
    (setuptools will stop shipping it) is a future broken install: fail now."""
    log = installed[2]
    found = [marker for marker in BUILD_WARNINGS if marker in log]
    assert not found, f"setuptools warned ({found}):\n{log}"


def test_the_wheel_ships_templates_and_data(installed):
    import zipfile

    names = set(zipfile.ZipFile(installed[3]).namelist())
    assert {"safeembodai_prompts/security/paper.j2", "safeembodai_prompts/system.j2",
            "safeembodai_core/data/paper_results.json", "safeembodai_core/py.typed"} <= names
    metadata = next(n for n in names if n.endswith(".dist-info/METADATA"))
    assert "License-Expression: MIT" in zipfile.ZipFile(installed[3]).read(metadata).decode()
    assert any(name.endswith("licenses/LICENSE") for name in zipfile.ZipFile(installed[3]).namelist())


def test_wheel_runs_a_scenario_outside_the_source_tree(installed, repo):
    python, work, _, _ = installed
    where = _run(python, "-c", "import safeembodai_core, safeembodai_plugins, safeembodai_prompts; "
                              "print(safeembodai_core.__file__); print(safeembodai_prompts.TEMPLATE_DIR)",
                 cwd=work).stdout
    assert str(repo) not in where and "site-packages" in where
    shutil.copy(repo / "scenarios" / "quickstart.yaml", work / "quickstart.yaml")
    done = _run(python, "-m", "safeembodai_core", "run", "quickstart.yaml", "--arm", "safeembodai", "--out", "out",
                cwd=work)
    assert "saved to" in done.stdout
    assert json.loads((work / "out" / "trial.json").read_text())["spec"]["environment"] == "flatland"


def test_example_plugin_is_found_through_its_entry_point(installed, repo):
    python, work, _, _ = installed
    _run(python, "-m", "pip", "install", "-q", "--no-deps", "--no-build-isolation", "--no-index",
         repo / "docs" / "examples" / "safeembodai-example-plugin")
    listing = json.loads(_run(python, "-m", "safeembodai_core", "plugins", "--json", cwd=work).stdout)
    example = next(row for row in listing if row["name"] == "example")
    assert example["source"] == "entry point"
    assert example["distribution"].startswith("safeembodai-example-plugin")
    assert {"validator:slow_zone", "validator:geofence", "attacker:polite_injection"} <= set(example["components"])
    assert "register_commands" in example["hooks"]
    assert _run(python, "-m", "safeembodai_core", "example-zones", cwd=work).stdout.startswith('{"zone_mm"')
    scenario = (repo / "scenarios" / "quickstart.yaml").read_text().replace(
        "safeembodai: {security_prefix: true, state_management: true, safety_validation: true}",
        "safeembodai: {safety_validation: true, validators: [slow_zone]}")
    (work / "zones.yaml").write_text(scenario)
    _run(python, "-m", "safeembodai_core", "run", "zones.yaml", "--arm", "safeembodai", "--out", "zones", cwd=work)
    steps = [json.loads(line) for line in (work / "zones" / "steps.jsonl").read_text().splitlines()]
    rules = {v["rule"] for step in steps for attempt in step["attempts"] for v in attempt["verdicts"]}
    assert rules == {"slow_zone"}
    fenced = _run(python, "-c", GEOFENCE_CHECK, cwd=work).stdout.splitlines()
    assert fenced[:2] == ["inside: True", "leaving: False"]
    assert fenced[2].startswith("geofence (signal 2): straight forward 390 mm leaves the robot's area: at most 183 mm")
    blocked = _run(python, "-m", "safeembodai_core", "plugins", "--json", cwd=work,
                   env={**os.environ, "SAFEEMBODAI_DISABLE_PLUGINS": "example"}).stdout
    assert "example" not in {row["name"] for row in json.loads(blocked)}
