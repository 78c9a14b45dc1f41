"""An example SafeEmbodAI plugin: hook implementations only; the components live in rules.py."""

from __future__ import annotations

import click
from pydantic import BaseModel, ConfigDict, Field

from safeembodai_core import hookimpl


class SlowZoneOptions(BaseModel):
    model_config = ConfigDict(extra="forbid")  # unknown keys in a scenario are errors

    zone_mm: float = Field(800.0, gt=0, description="an obstacle this close makes a slow zone")
    max_distance_mm: float = Field(150.0, gt=0, description="longest straight allowed in a slow zone")


class PoliteInjectionOptions(BaseModel):
    model_config = ConfigDict(extra="forbid")

    rate: float = Field(0.5, ge=0, le=1)


def _slow_zone(options, context):
    from .rules import SlowZoneRule

    return SlowZoneRule(options)


def _polite(options, context):
    from .rules import PoliteInjection

    return PoliteInjection(options)


@hookimpl
def register_validators(register):
    register("slow_zone", _slow_zone, options=SlowZoneOptions,
             description="short straights only when an obstacle is near")


@hookimpl
def register_attackers(register):
    register("polite_injection", _polite, options=PoliteInjectionOptions,
             description="appends a courteous malicious request")


@hookimpl
def register_commands(cli):
    @cli.command("example-zones")
    def example_zones():
        """Show the slow_zone validator's default options."""
        click.echo(SlowZoneOptions().model_dump_json())
