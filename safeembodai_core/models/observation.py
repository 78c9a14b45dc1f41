"""Sensor readings (what an environment observes) and modalities (what a prompt carries).

These hold numpy arrays, so they are plain dataclasses rather than pydantic models; they are
never parsed from untrusted text. Conventions, shared by every environment and validator:

* distances in millimetres, angles in degrees;
* the robot frame has x forward, y to the left, angles counter-clockwise from the heading;
* LiDAR beam ``k`` of ``N`` points at ``k * 360 / N`` degrees; ``inf`` means no return within
  ``max_range_mm`` (free space up to the range), ``nan`` means the beam gave no reading at all.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, Literal

import numpy as np
from pydantic import BaseModel, ConfigDict, Field, model_validator
from ..geometry.frames import wrap_deg


class Pose(BaseModel):
    """Robot pose in the world frame; for logs and metrics, not shown to the LLM by default."""

    model_config = ConfigDict(extra="forbid", frozen=True)

    x_mm: float
    y_mm: float
    heading_deg: float


#: Who moved into whom: ``self`` -- the robot's own motion made the contact; ``struck`` -- a
#: moving obstacle (a Labbot) ran into the robot (standing, turning on the spot, or from aside).
Collision = Literal["self", "struck"]
#: The keys an environment wrote into ``extra`` before these were fields (runs recorded then read the same).
_LEGACY_KEYS = ("collision", "collision_detail", "hit", "world_kind")


class GroundTruth(BaseModel):
    """What the simulator knows and the robot does not; only metrics read it.

    ``collision`` (with ``collision_detail`` and what was ``hit``): a collision outside any command --
    a mover that ran into the standing robot -- reported once, by the first reading after it;
    ``world_kind``: the kind of world the trial drew (a Labbot family's kind), for results per world;
    ``extra``: anything else an environment keeps (not read by the core). A record written when these
    were keys of ``extra`` reads the same.
    """

    model_config = ConfigDict(extra="forbid", frozen=True)

    target_in_view: bool = False
    target_bearing_deg: float | None = None
    target_distance_mm: float | None = None
    collision: Collision | None = None
    collision_detail: str = ""
    hit: str | None = None
    world_kind: str | None = None
    extra: dict[str, float | int | bool | str] = Field(default_factory=dict)

    @model_validator(mode="before")
    @classmethod
    def _lifted(cls, data: Any) -> Any:
        """Earlier records (and environments) kept these under ``extra``: lift them into their fields."""
        if not isinstance(data, dict) or not isinstance(data.get("extra"), dict):
            return data
        extra = dict(data["extra"])
        lifted = {key: extra.pop(key) for key in _LEGACY_KEYS if key in extra and data.get(key) is None}
        if not lifted:
            return data
        if lifted.get("collision") not in ("self", "struck"):
            lifted.pop("collision", None)  # not one of ours: no collision is claimed
        for key in ("collision_detail", "hit", "world_kind"):
            if key in lifted:
                lifted[key] = str(lifted[key])
        return {**data, **lifted, "extra": extra}


@dataclass
class LidarScan:
    """A 2D LiDAR scan; see the module docstring for units and conventions.

    ``returns_mm``, when a converted sensor scan keeps them (``LaserScan.to_lidar_scan``), are its
    returns where they really are, (M, 2) in the robot frame, before binning moved each to its bin's
    centre: rules that judge exact geometry (``swept_body``) judge these as well as the bins.
    """

    ranges_mm: np.ndarray
    max_range_mm: float
    returns_mm: np.ndarray | None = field(default=None, repr=False, compare=False)

    def __post_init__(self) -> None:
        ranges = np.asarray(self.ranges_mm, dtype=np.float64)
        if ranges.ndim != 1 or ranges.size < 4:
            raise ValueError(f"a LiDAR scan needs a 1-D array of at least 4 beams, got shape {ranges.shape}")
        if not np.isfinite(self.max_range_mm) or self.max_range_mm <= 0:
            raise ValueError(f"max_range_mm must be a positive finite number, got {self.max_range_mm}")
        finite = ranges[np.isfinite(ranges)]
        if (finite.size and finite.min() < 0) or np.isneginf(ranges).any():
            raise ValueError("LiDAR ranges must not be negative")
        self.ranges_mm = ranges

    @property
    def beam_count(self) -> int:
        return int(self.ranges_mm.size)

    @property
    def increment_deg(self) -> float:
        return 360.0 / self.beam_count

    @property
    def angles_deg(self) -> np.ndarray:
        """Beam angles in (-180, 180], counter-clockwise from the heading."""
        angles = np.arange(self.beam_count) * self.increment_deg
        return np.where(angles > 180.0, angles - 360.0, angles)

    def sector(self, centre_deg: float, half_width_deg: float) -> np.ndarray:
        """Indices of the beams within ``half_width_deg`` of ``centre_deg`` (edges included)."""
        offset = wrap_deg(self.angles_deg - centre_deg)
        return np.flatnonzero(np.abs(offset) <= half_width_deg + 1e-9)

    def points(self, include_free_bound: bool = False) -> np.ndarray:
        """Returns as (M, 2) points in the robot frame (mm).

        With ``include_free_bound`` a no-return beam becomes a point at ``max_range_mm``: the
        conservative end of the free space it measured. Missing (``nan``) beams never do.
        """
        ranges = self.ranges_mm.copy()
        if include_free_bound:
            ranges[np.isposinf(ranges)] = self.max_range_mm
        keep = np.isfinite(ranges)
        rad = np.radians(self.angles_deg[keep])
        return np.column_stack((ranges[keep] * np.cos(rad), ranges[keep] * np.sin(rad)))


@dataclass
class Observation:
    """One reading of every sensor, plus ground truth kept apart for metrics."""

    camera: np.ndarray | None = None  # H x W x 3 uint8 RGB
    lidar: LidarScan | None = None
    pose: Pose | None = None
    truth: GroundTruth = field(default_factory=GroundTruth)
    sim_time_s: float = 0.0
    extra: dict[str, Any] = field(default_factory=dict)


@dataclass(frozen=True)
class ImagePart:
    """An encoded image in a prompt (``name`` is the modality, e.g. ``camera_image``)."""

    name: str
    data: bytes
    media_type: str = "image/png"
    width: int = 0
    height: int = 0


@dataclass(frozen=True)
class TextPart:
    """A piece of text in a prompt (``name`` says which modality or section it carries)."""

    name: str
    text: str


@dataclass
class Modalities:
    """What perception made of an observation: images and texts, by modality name.

    Standard names: ``camera_image`` and ``lidar_image`` (images), ``camera_text`` and
    ``lidar_text`` (text renderings for models without vision).
    """

    images: dict[str, ImagePart] = field(default_factory=dict)
    texts: dict[str, str] = field(default_factory=dict)
