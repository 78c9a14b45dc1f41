"""The options of the ``outside`` backend and environment (the package registers them)."""

from __future__ import annotations

from typing import Literal

from pydantic import Field

from safeembodai_core.contracts.descriptions import BackendDescription, BackendOptions, EnvironmentOptions


class OutsideOptions(BackendOptions):
    """``client``: who sent the commands: a rosbridge client (serve-robot) or an MCP client (guard-mcp)."""

    client: Literal["rosbridge", "mcp"] = "rosbridge"

    def describe(self) -> BackendDescription:
        if self.client == "mcp":
            return BackendDescription(model="an outside MCP client (who or what it was is not recorded)",
                                      model_source="safeembodai guard-mcp: tool calls received, no prompt sent")
        return BackendDescription(model="an outside client over rosbridge (who or what it was is not recorded)",
                                  model_source="safeembodai serve-robot: commands received, no prompt sent")


class OutsideRobotOptions(EnvironmentOptions):
    """``rosbridge``: where the robot was reached (``ws://HOST:PORT``), for the record."""

    rosbridge: str = Field("", max_length=256)
