"""The decoding settings the litellm backends' options name (light: no model or schema code here).

:mod:`.messages` builds the requests from them.
"""

from __future__ import annotations

from typing import Literal

ImageDetail = Literal["low", "high", "auto"]
JsonMode = Literal["json_schema", "json_schema_enum", "json_object", "none"]
# names of earlier releases, still accepted: json_object_schema had the enum form's shape, unbounded
LEGACY_JSON_MODES: dict[str, JsonMode] = {"json_object_schema": "json_schema_enum", "off": "none"}
#: ``max_tokens`` of the ``local`` backend (its option's default), when a caller names none: with the
#: default limits, the longest answer then leaves 268 characters to ``planning`` (:func:`.messages.text_caps`).
DEFAULT_MAX_TOKENS = 2048
