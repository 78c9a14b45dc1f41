"""``safeembodai serve-robot``: one room of a scenario served as a rosbridge v2 robot.

:func:`prepare_session` checks everything before anything is bound or written: the environment
label, that the room can be driven by velocity (``Environment.drive``), the rates; it builds the
room with no think time (the client's own latency is the time it thinks: the world moves on the
wall clock meanwhile) and draws it from the seed. :meth:`Session.serve` then starts the rosbridge
server (:class:`~safeembodai_core.rosbridge.server.RosbridgeServer`), offers the room's topics,
accepts velocity commands and runs :class:`~.served_room.ServedRoom` until stopped; the run folder
(:mod:`.session_record`) is written as it goes and finished whatever ends it.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any, Callable, Sequence

import structlog

from ..runs.folder import RunFolder
from ..plugin.building import ComponentBuilder
from ..contracts.components import Environment
from ..errors import SafeEmbodAIError
from ..plugin.manager import Plugins
from ..plugin.refs import ComponentRef
from ..scenario import Scenario
from . import messages
from .served_room import Rates, ServedRoom
from .session_bag import STORAGES as BAG_STORAGES
from .session_record import SessionRecord, session_scenario

log = structlog.get_logger(__name__)

#: What the served robot publishes: topic -> type.
OFFERED = {"/scan": messages.LASER_SCAN, "/odom": messages.ODOMETRY,
           "/camera/image_raw/compressed": messages.COMPRESSED_IMAGE, "/safeembodai/events": messages.STRING}
#: The velocity topic and the types it takes.
COMMAND_TOPIC = "/cmd_vel"
COMMAND_TYPES = (messages.TWIST, messages.TWIST_STAMPED)


@dataclass
class Session:
    """A prepared session: the room drawn, the record's scenario, where it is served and recorded."""

    scenario: Scenario
    plugins: Plugins
    environment: Environment
    label: str
    seed: int
    host: str
    port: int
    folder: Path
    speed: float = 1.0
    rates: Rates = field(default_factory=Rates)
    bag: str | None = "mcap"
    allowed_origins: tuple[str, ...] = ()
    room: ServedRoom | None = None
    server: Any = None

    def serve(self, on_ready: Callable[["Session"], None] | None = None) -> SessionRecord:
        """Serve until :meth:`stop` (or the process's SIGINT/SIGTERM, wired by the caller); the record
        written. The server binds first: a port in use fails before the run folder is made. ``on_ready``
        is told once the server listens and the room runs."""
        from ..rosbridge.server import RosbridgeServer

        server = RosbridgeServer(self.host, self.port, node="/safeembodai_robot",
                                 allowed_origins=self.allowed_origins)
        for topic, type_ in OFFERED.items():
            server.offer_topic(topic, type_)
        server.accept_topic(COMMAND_TOPIC, COMMAND_TYPES, self._command)
        record: SessionRecord | None = None
        try:
            server.start()
            self.server, self.port = server, server.port
            record = SessionRecord(self.scenario, self.plugins, self.folder, self.seed, bag=self.bag,
                                   about=self._about())
            self.room = ServedRoom(self.environment, record, server.publish, seed=self.seed, speed=self.speed,
                                   rates=self.rates, time_limit_s=_time_limit(self.environment))
            log.info("serve_robot.listening", host=self.host, port=self.port, folder=str(self.folder))
            if on_ready is not None:
                on_ready(self)
            self.room.run()
        finally:
            server.stop()
            if record is not None:
                record.close()
            self.environment.close()
        assert record is not None
        return record

    def _about(self) -> dict[str, Any]:
        """What the bag says of the session at its start, besides the trial: the robot, the rates."""
        robot = self.environment.robot
        return {"robot": {"radius_mm": robot.radius_mm, "width_mm": robot.width_mm, "length_mm": robot.length_mm},
                "served": {"speed": self.speed, **asdict(self.rates)}}

    def _command(self, type_: str, message: Any, client: str) -> None:
        if self.room is None:
            raise ValueError("the room is not running yet")
        self.room.command(message, COMMAND_TOPIC, type_, client)

    def stop(self, reason: str = "stopped") -> None:
        """End the session (any thread, a signal handler too)."""
        if self.room is not None:
            self.room.stop(reason)


def _time_limit(environment: Environment) -> float | None:
    options = getattr(environment, "options", None)
    limit = getattr(options, "max_sim_time_s", None)
    return float(limit) if isinstance(limit, (int, float)) else None


def served_ref(ref: ComponentRef, plugins: Plugins) -> ComponentRef:
    """``ref`` with no think time, when its options have one: the wall clock is the time here."""
    model = plugins.registry.get("environment", ref.use).options
    if "think_time_s" not in model.model_fields:
        return ref
    return ref.model_copy(update={"options": {**ref.options, "think_time_s": 0.0, "think_time_per_call": False}
                                  if "think_time_per_call" in model.model_fields
                                  else {**ref.options, "think_time_s": 0.0}})


def prepare_session(scenario: Scenario, plugins: Plugins, *, label: str | None = None, host: str = "127.0.0.1",
                    port: int = 9090, out: str | Path = "runs", speed: float = 1.0,
                    rates: Rates | None = None, bag: str | None = "mcap",
                    allowed_origins: Sequence[str] = ()) -> Session:
    """Check and build a session (module docstring); raises :class:`SafeEmbodAIError` naming what
    is wrong, before any folder or socket."""
    if bag not in (None, *BAG_STORAGES):
        raise SafeEmbodAIError(f"--bag {bag!r}: use one of {', '.join(BAG_STORAGES)}, or none")
    labels = [ref.key for ref in scenario.environments]
    label = label or labels[0]
    if label not in labels:
        raise SafeEmbodAIError(f"--environment {label!r} is not in the scenario; choose from {', '.join(labels)}")
    ref = served_ref(scenario.environment(label), plugins)
    served = scenario.model_copy(update={"environments": [ref if r.key == label else r for r in scenario.environments]})
    record_scenario = session_scenario(served, label)
    environment = ComponentBuilder(served, plugins).environment(label)
    environment.reset(scenario.seed)
    if environment.drive(0.0, 0.0, 0.0) is None:  # a hold of no time: the default's None, or nothing moves
        environment.close()
        raise SafeEmbodAIError(f"environment {ref.use!r} ({label}) cannot be driven by velocity (it has no "
                               "Environment.drive): serve-robot serves rooms that can, such as the pybullet rooms")
    folder = RunFolder.create(out, record_scenario).path  # made by the record, once the server listens
    return Session(record_scenario, plugins, environment, label, scenario.seed, host, port, folder, speed,
                   rates or Rates(), bag, tuple(allowed_origins))
