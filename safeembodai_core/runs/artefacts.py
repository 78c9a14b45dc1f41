"""What a trial leaves beside its records, written as it ends: its picture, its ROS 2 bag, its Rerun
recording.

The trial runner (:class:`~safeembodai_core.runs.runner.ScenarioRunner`) knows only the narrow
interface of :class:`TrialArtefacts`: whether the trial must be captured (:attr:`~TrialArtefacts.capture`)
and :meth:`~TrialArtefacts.after_trial`. Where the files go is a :class:`~.trial_files.TrialFiles`
(the run folder, or a Ray worker's relay to the coordinator); which ones a run writes is
:class:`ArtefactSettings`, read from the run folder's markers so that every worker of a run writes
the same (``ablate --bags`` and ``ablate --rerun`` write the markers before any trial runs).

Every artefact is written after the trial's result is stored. A picture that cannot be *drawn* costs
only the picture (a warning); a file that cannot be *written* stops the run with an error naming it
(the result is stored; a resume draws a missing picture again, ``safeembodai export`` makes a bag or
a recording again from the run folder).
"""

from __future__ import annotations

from typing import Any, Callable

from ..logs import get_logger
from ..models import TrialResult, TrialSpec, StepRecord
from ..plugin.manager import Plugins
from ..scenario import Scenario
from .trial_files import ArtefactSettings, TrialFiles

log = get_logger(__name__)


class TrialArtefacts:
    """Writes the artefacts of the trials of ``scenario`` into ``files`` (None: writes nothing).

    ``pictures``: draw each trial's picture; ``settings``: the bags and recordings asked for."""

    def __init__(self, scenario: Scenario, plugins: Plugins, files: TrialFiles | None, *, pictures: bool,
                 settings: ArtefactSettings) -> None:
        self.scenario, self.plugins, self.files = scenario, plugins, files
        self.pictures = pictures and files is not None
        self.settings = settings
        self._simulated: str | None = None  # the backend's banner for pictures, read once

    @property
    def capture(self) -> bool:
        """Whether a trial must be run under a :class:`~.loop.capture.TrialCapture` (its bag and
        recording are made of what the capture saw)."""
        return self.files is not None and (self.settings.bag_storage is not None or self.settings.recordings)

    def after_trial(self, spec: TrialSpec, environment: Any, capture: Any, result: TrialResult,
                    steps: Callable[[], list[StepRecord]]) -> None:
        """Write what the trial leaves, once its result is stored; ``steps`` reads its records
        (only when a bag or a recording needs them)."""
        if self.pictures:
            self.save_picture(environment, result)
        if capture is None or self.files is None:
            return
        records = steps()
        if self.settings.bag_storage is not None:
            self.files.bag(spec.trial_id, self.bag_messages(spec, capture, records, result, environment.robot),
                           self.settings.bag_storage)
        if self.settings.recordings:
            from .rerun_recording import recording_bytes

            self.files.recording(spec.trial_id, recording_bytes(spec, records, result, capture, environment.robot))

    def bag_messages(self, spec: TrialSpec, capture: Any, records: list[Any], result: TrialResult | None,
                     robot: Any) -> list[Any]:
        """The bag of one trial (:func:`~safeembodai_core.ros.bag_export.trial_messages`), with the
        scenario's word on the arm's defences and the limits in ``/safeembodai/trial``."""
        from ..ros.bag_export import trial_messages

        about = {"scenario": self.scenario.name, "arm": self.scenario.arms[spec.arm].model_dump(mode="json"),
                 "limits": self.scenario.limits.model_dump(mode="json")}
        return trial_messages(spec, records, result, capture, robot, about)

    def picture(self, environment: Any, result: TrialResult) -> bytes | None:
        """The trial's picture as ``environment`` draws it, captioned with the trial's id, arm and
        condition and, for a simulated backend, that it is one (``runs/captions.py``); None when
        the environment draws none. Raises what the environment's drawing raises."""
        from .captions import caption_lines, captioned
        from ..scenario.describe import describe_backend

        picture = environment.trajectory_png(result.trajectory, result.outcome)
        if not picture:
            return None
        if self._simulated is None:  # the backend's banner, once ("" for an LLM)
            self._simulated = describe_backend(self.scenario, self.plugins).simulated or ""
        return captioned(picture, caption_lines(result.spec, self._simulated or None))

    def save_picture(self, environment: Any, result: TrialResult) -> bool:
        """Draw and write the trial's picture (:meth:`picture`); False when none was written.

        A drawing bug only costs the picture (a warning). A picture that cannot be written (a
        full disk, ``trajectories`` not a folder) stops the run with an error naming the file.
        """
        try:
            picture = self.picture(environment, result)
        except Exception as error:  # a picture is a convenience: never lose a trial over it
            log.warning("trajectory.failed", trial=result.spec.trial_id, error=str(error))
            return False
        if not picture or self.files is None:
            return False
        self.files.picture(result.spec.trial_id, picture)
        return True
