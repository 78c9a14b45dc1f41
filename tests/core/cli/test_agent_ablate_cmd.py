"""``safeembodai agent-ablate``: registered like the other commands, with ``ablate``'s scenario options, and refusing
before any folder is made what it cannot run."""

from __future__ import annotations

import pytest

from safeembodai_core.cli import cli


def test_it_is_listed_with_the_scenario_options(cli_runner):
    helped = cli_runner.invoke(cli, ["agent-ablate", "--help"])
    assert helped.exit_code == 0
    for option in ("--out", "--seed", "--set", "--backend", "--ros-mcp", "--decider", "--no-report"):
        assert option in helped.output


def test_without_ros_mcp_it_says_how_to_install_it_and_makes_no_folder(cli_runner, repo, tmp_path, monkeypatch):
    pytest.importorskip("mcp", reason="the MCP agent needs the MCP SDK: pip install -e '.[mcp]'")
    monkeypatch.delenv("SAFEEMBODAI_ROS_MCP", raising=False)
    monkeypatch.setenv("PATH", str(tmp_path))
    result = cli_runner.invoke(cli, ["agent-ablate", str(repo / "scenarios/mcp.yaml"), "--out", str(tmp_path / "runs")])
    assert result.exit_code != 0 and "ros-mcp was not found" in str(result.exception)
    assert not (tmp_path / "runs").exists()


def test_an_arm_no_route_gives_is_refused_by_name(cli_runner, repo, tmp_path):
    pytest.importorskip("mcp", reason="the MCP agent needs the MCP SDK: pip install -e '.[mcp]'")
    result = cli_runner.invoke(cli, ["agent-ablate", str(repo / "scenarios/mcp.yaml"), "--out", str(tmp_path / "runs"),
                                     "--set", "arms.ros_mcp_direct.security_prefix=true"])
    assert result.exit_code != 0 and "arm 'ros_mcp_direct'" in str(result.exception)
    assert not (tmp_path / "runs").exists()
