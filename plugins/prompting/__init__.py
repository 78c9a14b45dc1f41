"""``jinja``: the secure-prompting builder (Table I of the paper) on sandboxed Jinja templates.

Templates come from ``template_dir`` when set (the user's own folder, searched first), else from
the built-in ``safeembodai_prompts`` package. The arm's ``security_prefix`` picks the variant
``security/<name>.j2`` (``paper``, ``hierarchy``, ``spotlight``, ``sandwich`` ship built in).
Untrusted text (the human instruction, anything an LLM wrote) is passed to templates as data,
never as template source, and templates render in a sandbox with ``StrictUndefined``. Every
option is documented in ``docs/defences.md``.
"""

from __future__ import annotations

from pathlib import Path
from pydantic import BaseModel, ConfigDict, Field

from safeembodai_core.hookspecs import hookimpl
from safeembodai_core.plugin.registry import lazy


class JinjaPromptOptions(BaseModel):
    """Options of the ``jinja`` prompt builder."""

    model_config = ConfigDict(extra="forbid")

    template_dir: Path | None = Field(None, description="folder searched before the built-in templates")
    system_template: str = Field("system.j2", min_length=1, description="template of the system prompt Y")
    user_template: str = Field("user.j2", min_length=1, description="template of the user prompt I_i")
    max_instruction_chars: int = Field(2000, ge=50, le=100_000, description="longer human instructions are cut")
    max_reference_chars: int = Field(300, ge=20, le=10_000,
                                     description="each LLM-written text of R_{i-1} is cut to this length")
    max_failures: int = Field(6, ge=0, le=100, description="most recent refusal reasons shown on a retry")
    max_failure_chars: int = Field(400, ge=40, le=10_000, description="each refusal reason is cut to this length")


@hookimpl
def register_prompt_builders(register):
    register("jinja", lazy(f"{__name__}.builder", "JinjaPromptBuilder"), options=JinjaPromptOptions,
             description="system prompt Y = {B, p} and user prompt I_i from sandboxed Jinja templates")
