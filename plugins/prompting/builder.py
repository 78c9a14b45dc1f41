"""Render the system and user prompts from Jinja templates."""

from __future__ import annotations

import json
from pathlib import Path

import jinja2
from jinja2.sandbox import SandboxedEnvironment

from safeembodai_core.components import PromptBuilder
from safeembodai_core.errors import ComponentError
from safeembodai_core.models import ImagePart, Prompt, PromptRequest, TextPart
from safeembodai_core.models.response import schema_outline
from safeembodai_prompts import TEMPLATE_DIR

IMAGE_ORDER = ("camera_image", "lidar_image")


class JinjaPromptBuilder(PromptBuilder):
    def __init__(self, options) -> None:
        self.options = options
        folders = [str(TEMPLATE_DIR)]
        if options.template_dir is not None:
            if not Path(options.template_dir).is_dir():
                raise ComponentError(f"prompt builder 'jinja': template_dir {options.template_dir} is not a folder")
            folders.insert(0, str(options.template_dir))
        self.env = SandboxedEnvironment(
            loader=jinja2.FileSystemLoader(folders),
            undefined=jinja2.StrictUndefined,
            autoescape=False,
            keep_trailing_newline=False,
        )
        self.env.filters["quoted"] = lambda value: json.dumps(str(value), ensure_ascii=False)
        self.outline = schema_outline()
        self._templates: dict[str, jinja2.Template] = {}

    def _render(self, name: str, **values) -> str:
        try:
            template = self._templates.get(name) or self.env.get_template(name)
            self._templates[name] = template
            return template.render(**values).strip()
        except jinja2.TemplateNotFound:
            raise ComponentError(f"prompt template {name!r} not found in {', '.join(self.env.loader.searchpath)}") from None
        except jinja2.TemplateSyntaxError as error:
            raise ComponentError(f"prompt template {error.filename or name}:{error.lineno}: syntax error: {error.message}") from None
        except jinja2.UndefinedError as error:
            raise ComponentError(f"prompt template {name!r}: {error.message}") from None

    def build(self, request: PromptRequest) -> Prompt:
        m = request.modalities
        sections = {"role", "task", "capabilities", "response_format", "methods"}
        prefix = ""
        if request.security_prefix is not None:
            prefix = self._render(f"security/{request.security_prefix}.j2")
            sections.add("security_prefix")
        system = self._render(
            self.options.system_template,
            task=request.task,
            security_prefix=prefix,
            has_camera_image="camera_image" in m.images,
            has_lidar_image="lidar_image" in m.images,
            has_text=bool(m.texts),
            has_reference=request.reference_state is not None,
            response_outline=self.outline,
            max_distance_mm=f"{request.limits.max_distance_mm:g}",
            max_angle_deg=f"{request.limits.max_angle_deg:g}",
            max_signals=request.limits.max_signals,
        )
        reference = None
        if request.reference_state is not None:
            sections.add("reference_state")
            reference = {
                "step": request.reference_state.step,
                "executed": [
                    {"signal": item.signal.describe(), "result": _result_text(item.result)}
                    for item in request.reference_state.executed
                ],
                "planning": request.reference_state.planning,
                "perception": request.reference_state.perception,
            }
        if request.failures:
            sections.add("failures")
        user = self._render(
            self.options.user_template,
            instruction=request.instruction,
            texts=sorted(m.texts.items()),
            reference=reference,
            failures=list(request.failures),
        )
        parts: list[TextPart | ImagePart] = [TextPart("user", user)]
        parts.extend(m.images[name] for name in IMAGE_ORDER if name in m.images)
        parts.extend(image for name, image in sorted(m.images.items()) if name not in IMAGE_ORDER)
        return Prompt(system=system, user=tuple(parts), sections=frozenset(sections))


def _result_text(result) -> str:
    if result.collided:
        return f"collided ({result.detail})"
    if result.stopped:
        return f"stopped ({result.detail})"
    if result.distance_mm:
        return f"moved {abs(result.distance_mm):.0f} mm"
    return f"turned {abs(result.angle_deg):.0f} deg"
