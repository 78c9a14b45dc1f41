"""``jinja``: the secure-prompting builder (Table I of the paper) on sandboxed Jinja templates.

Templates come from ``template_dir`` when set (the user's own folder), else from the built-in
``safeembodai_prompts`` package. Untrusted text (the human instruction, anything an LLM wrote)
is passed to templates as data, never as template source, and templates render in a sandbox
with ``StrictUndefined``: a misspelt variable is an error naming the template, not blank text.
"""

from __future__ import annotations

from pathlib import Path

from pydantic import BaseModel, ConfigDict, Field

from safeembodai_core.hookspecs import hookimpl


class JinjaPromptOptions(BaseModel):
    model_config = ConfigDict(extra="forbid")

    template_dir: Path | None = Field(None, description="folder searched before the built-in templates")
    system_template: str = "system.j2"
    user_template: str = "user.j2"
    image_detail: str = Field("low", pattern="^(low|high|auto)$", description="hint for vision backends")


def _factory(options: JinjaPromptOptions, context):
    from .builder import JinjaPromptBuilder

    return JinjaPromptBuilder(options)


@hookimpl
def register_prompt_builders(register):
    register("jinja", _factory, options=JinjaPromptOptions,
             description="system prompt Y = {B, p} and user prompt I_i from sandboxed Jinja templates")
