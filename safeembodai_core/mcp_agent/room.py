"""One trial's served room, in a thread of this process, with a sign the camera reads.

:class:`RoomInThread` serves a room of the scenario the way ``safeembodai serve-robot`` does
(:func:`~safeembodai_core.serve_robot.session.prepare_session`: the room drawn from the trial's seed,
no think time, recorded as a run folder of its own, the judge of the trial) on a free port of
``127.0.0.1``. It adds one topic: ``/camera/text`` (``std_msgs/msg/String``, latched), what an OCR
node beside the camera would publish -- the text the camera reads, empty when it reads none. The
trial writes on it (:meth:`RoomInThread.show_text`) what an attacker put in front of the camera.

It keeps the room's latest ground truth and pose as the room computes them for its own camera frame
(on the room's thread: the room is never touched from another), for the trial's records (the target
in view, for TLR) and for attackers that aim at the target.
"""

from __future__ import annotations

import threading
from pathlib import Path
from typing import Any

from ..errors import SafeEmbodAIError
from ..models import GroundTruth, Pose, TrialResult
from ..plugin.manager import Plugins
from ..scenario import Scenario

CAMERA_TEXT = "/camera/text"
STRING = "std_msgs/msg/String"
START_TIMEOUT_S = 30.0


class RoomInThread:
    """A served room for one trial (module docstring); :meth:`start`, then :meth:`stop` once."""

    def __init__(self, scenario: Scenario, plugins: Plugins, label: str, seed: int, out: Path) -> None:
        from ..serve_robot.session import prepare_session

        self.session = prepare_session(scenario.model_copy(update={"seed": seed}), plugins, label=label, port=0,
                                       out=out, bag=None)
        self.truth = GroundTruth()
        self.pose: Pose | None = None
        self._thread: threading.Thread | None = None
        self._failed: BaseException | None = None
        environment = self.session.environment
        observe = environment.observe

        def observed() -> Any:  # on the room's thread: the frame it is about to publish, and its truth
            observation = observe()
            self.truth, self.pose = observation.truth, observation.pose
            return observation

        setattr(environment, "observe", observed)  # the room calls it for each frame: the truth rides along

    @property
    def environment(self) -> Any:
        return self.session.environment

    @property
    def port(self) -> int:
        return self.session.port

    @property
    def folder(self) -> Path:
        return self.session.folder

    def start(self) -> "RoomInThread":
        ready = threading.Event()

        def serve() -> None:
            try:
                self.session.serve(on_ready=lambda session: self._ready(session, ready))
            except BaseException as error:  # recorded by the room as its outcome; said again by stop()
                self._failed = error

        self._thread = threading.Thread(target=serve, name="served-room", daemon=True)
        self._thread.start()
        if not ready.wait(START_TIMEOUT_S):
            self.stop()
            raise SafeEmbodAIError(f"the served room did not start within {START_TIMEOUT_S:g} s"
                                   + (f": {self._failed}" if self._failed else ""))
        return self

    def _ready(self, session: Any, ready: threading.Event) -> None:
        session.server.offer_topic(CAMERA_TEXT, STRING, latch=True)
        self.show_text("")
        ready.set()

    def show_text(self, text: str) -> None:
        """What the camera reads from now on (latched: each new subscription gets it at once)."""
        self.session.server.publish(CAMERA_TEXT, {"data": text})

    @property
    def outcome(self) -> Any:
        """The room's outcome so far (None: none yet)."""
        room = self.session.room
        return None if room is None else room.outcome

    @property
    def driven_mm(self) -> float:
        room = self.session.room
        return 0.0 if room is None else float(room.record.distance_mm)

    def stop(self, reason: str = "the agent's run ended") -> TrialResult | None:
        """End the session; the room's own result (None when it never ran)."""
        self.session.stop(reason)
        if self._thread is not None:
            self._thread.join(START_TIMEOUT_S)
        room = self.session.room
        return None if room is None else room.record.result
