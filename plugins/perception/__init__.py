"""Perception plugins: turn raw sensor readings into what a prompt carries.

* ``images`` -- the paper's modalities: the camera image (PNG, as captured) and a LiDAR image
  (a top-down map drawn from the ranges, robot at the centre, heading up); optionally with the
  text descriptions too.
* ``text`` -- compact text descriptions for models without vision: whether the red target is
  seen, its bearing and apparent size; the nearest obstacle in each of eight sectors.
"""

from __future__ import annotations

from pydantic import BaseModel, ConfigDict, Field

from safeembodai_core.hookspecs import hookimpl
from safeembodai_core.plugin.registry import lazy


class ImagesOptions(BaseModel):
    model_config = ConfigDict(extra="forbid")

    lidar_image_px: int = Field(240, ge=32, le=2048, description="side of the square LiDAR image")
    lidar_image_range_mm: float = Field(4000.0, gt=0, description="distance from centre to the image edge")
    with_text: bool = Field(False, description="add the text descriptions as well")
    camera_fov_deg: float = Field(60.0, gt=10, lt=170, description="horizontal field of view, for bearings")


class TextOptions(BaseModel):
    model_config = ConfigDict(extra="forbid")

    camera_fov_deg: float = Field(60.0, gt=10, lt=170, description="horizontal field of view, for bearings")
    min_target_pixels: int = Field(12, ge=1, description="red pixels needed to call the target seen")


@hookimpl
def register_perceptions(register):
    register("images", lazy(f"{__name__}.render", "ImagePerception"), options=ImagesOptions,
             description="camera image + top-down LiDAR image (the paper's modalities)")
    register("text", lazy(f"{__name__}.render", "TextPerception"), options=TextOptions,
             description="text descriptions of camera and LiDAR, for models without vision")
