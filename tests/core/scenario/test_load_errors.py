"""Every problem of a scenario at once, in file order, with the closest known key for a misspelt one."""

from __future__ import annotations

import subprocess
import sys

import pytest

from safeembodai_core.errors import ScenarioError
from safeembodai_core.scenario import load_scenario

BAD = """\
name: bad
trails: 3
environments: [flatland]
arms:
  baseline: {security_prefx: true}
  safeembodai:
    safety_validation: true
    validators: [{use: lidar_clearance, options: {half_angle: 20}}]
conditions:
  attack: {attackers: [{use: prompt_injection, options: {rate: 3}}]}
"""


def problems(path, plugins, overrides=()) -> list[str]:
    with pytest.raises(ScenarioError) as error:
        load_scenario(path, overrides, plugins.registry)
    head, *lines = str(error.value).splitlines()
    assert head == "invalid scenario:"
    return [line.strip() for line in lines]


def test_schema_errors_and_component_option_errors_are_reported_together(tmp_path, plugins):
    path = tmp_path / "bad.yaml"
    path.write_text(BAD)
    assert problems(path, plugins) == [
        f"{path}:2: trails: Extra inputs are not permitted; did you mean 'trials'?",
        f"{path}:5: arms.baseline.security_prefx: Extra inputs are not permitted; did you mean 'security_prefix'?",
        f"{path}:8: arms.safeembodai.validators.0.options.half_angle: Extra inputs are not permitted; did you mean "
        "'half_angle_deg'? (validator 'lidar_clearance' from plugin 'validators')",
        f"{path}:10: conditions.attack.attackers.0.options.rate: Input should be less than or equal to 1 "
        "(attacker 'prompt_injection' from plugin 'attackers')",
    ]


def test_an_unknown_profile_does_not_hide_the_other_problems(tmp_path, plugins):
    path = tmp_path / "bad.yaml"
    path.write_text("profile: eyesim_relase\n" + BAD)
    found = problems(path, plugins)
    assert found[0].startswith(f"{path}:1: profile: ") and len(found) == 5


def test_a_misspelt_set_key_gets_a_suggestion(repo, plugins):
    found = problems(repo / "scenarios" / "quickstart.yaml", plugins, ["trails=3", "environments.0.use=flatlnd"])
    assert "--set trails: trails: Extra inputs are not permitted; did you mean 'trials'?" in found
    assert any("no environment named 'flatlnd'. Did you mean 'flatland'?" in line for line in found), found


def test_the_cli_prints_the_suggestion(repo):
    done = subprocess.run([sys.executable, "-m", "safeembodai_core", "run", str(repo / "scenarios" / "quickstart.yaml"),
                           "--set", "trails=3"], capture_output=True, text=True, timeout=120)
    assert done.returncode == 1 and "did you mean 'trials'?" in done.stderr and "Traceback" not in done.stderr


@pytest.mark.parametrize("arms, conditions", [
    ("{a__b: {}, a: {}}", "{c: {}, b__c: {}}"),  # MO__a__b__c__0 twice
    ("{a_: {}, a: {}}", "{b: {}, _b: {}}"),  # MO__a___b__0 twice
])
def test_names_that_would_give_two_trials_one_file_name_are_refused(tmp_path, plugins, arms, conditions):
    """A trial's picture and bag are named by its cell's names joined with '__'
    (run_files.trial_file_name): names that could join into another cell's are refused, naming it."""
    from safeembodai_core.runs.files import trial_file_name

    path = tmp_path / "clash.yaml"
    path.write_text(f"name: clash\nenvironments: [MO]\narms: {arms}\nconditions: {conditions}\n")
    found = problems(path, plugins)
    assert any("must not contain '__' or start or end with '_'" in line for line in found), found
    first, second = (f"MO/{a}/{c}/0" for a, c in (("a__b", "c"), ("a", "b__c"))) if "__" in arms else \
        (f"MO/{a}/{c}/0" for a, c in (("a_", "b"), ("a", "_b")))
    assert trial_file_name(first) == trial_file_name(second)  # what the refusal prevents
