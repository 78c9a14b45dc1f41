"""Where prompt templates come from and how they fail: a sandboxed Jinja environment.

Templates are looked up in the user's ``template_dir`` first, then in the built-in
``safeembodai_prompts`` package (found next to its ``__init__.py``, in a source tree and in an
installed wheel alike). They render in a :class:`~jinja2.sandbox.SandboxedEnvironment` with
``StrictUndefined``: a misspelt variable is an error, never blank text. Every failure is a
:class:`PromptTemplateError` naming the template file (and the line when Jinja knows it).

Untrusted text is only ever passed *as a value*: Jinja never re-parses the value of a variable,
so ``{{ ... }}`` or ``{% ... %}`` inside a human instruction is printed literally.
"""

from __future__ import annotations

import re
from functools import lru_cache
from pathlib import Path
from types import TracebackType
from typing import Any

import jinja2
from jinja2.sandbox import SandboxedEnvironment

from safeembodai_core.errors import ComponentError
from safeembodai_core.trust.quoting import quote_untrusted
# prompts/ imports as safeembodai_prompts through setuptools' editable import hook, which mypy cannot follow
from safeembodai_prompts import TEMPLATE_DIR  # type: ignore[import-not-found]

SECURITY_FOLDER = "security"
_VARIANT_NAME = re.compile(r"^[A-Za-z0-9_][A-Za-z0-9_.-]*$")


class PromptTemplateError(ComponentError):
    """A prompt template is missing, does not parse, or uses a variable nobody passes."""


def quoted(value: Any) -> str:
    """``value`` as a JSON string literal: quotes and newlines escaped, so it cannot break out.

    The same quoting as the answer parser's refusal reasons (:mod:`safeembodai_core.trust.quoting`).
    """
    return quote_untrusted(value)


def _template_line(tb: TracebackType | None, filename: str | None) -> int | None:
    """The template line of the innermost frame Jinja attributed to ``filename``."""
    line = None
    while tb is not None:
        if filename and tb.tb_frame.f_code.co_filename == filename:
            line = tb.tb_lineno
        tb = tb.tb_next
    return line


@lru_cache(maxsize=16)
def _environment(folders: tuple[str, ...]) -> SandboxedEnvironment:
    """One sandboxed environment per search path, shared by every builder of the process.

    Jinja keeps compiled templates in it (and recompiles a template whose file changed), so the
    builders of successive trials do not compile the same templates again.
    """
    env = SandboxedEnvironment(
        loader=jinja2.FileSystemLoader(list(folders)),
        undefined=jinja2.StrictUndefined,
        autoescape=False,
        keep_trailing_newline=False,
        trim_blocks=True,
        lstrip_blocks=True,
    )
    env.filters["quoted"] = quoted
    return env


class TemplateSet:
    """The templates of one prompt builder: user folder first, built-ins second."""

    def __init__(self, template_dir: Path | None = None) -> None:
        folders = [str(TEMPLATE_DIR)]
        if template_dir is not None:
            folder = Path(template_dir).expanduser()
            if not folder.is_dir():
                raise PromptTemplateError(
                    f"prompt builder 'jinja': template_dir {str(folder)!r} is not a folder"
                )
            folders.insert(0, str(folder.resolve()))
        self.folders = folders
        self.env = _environment(tuple(folders))
        self._cache: dict[str, jinja2.Template] = {}

    def load(self, name: str) -> jinja2.Template:
        """The template ``name`` (cached); a clear error when it is missing or does not parse."""
        if name in self._cache:
            return self._cache[name]
        try:
            template = self.env.get_template(name)
        except jinja2.TemplateNotFound:
            raise PromptTemplateError(
                f"prompt template {name!r} not found in {' or '.join(self.folders)}"
            ) from None
        except jinja2.TemplateSyntaxError as error:
            where = error.filename or name
            raise PromptTemplateError(
                f"prompt template {where}:{error.lineno}: syntax error: {error.message}"
            ) from None
        self._cache[name] = template
        return template

    def _fail(self, template: jinja2.Template, error: Exception) -> PromptTemplateError:
        filename = template.filename or template.name
        line = _template_line(error.__traceback__, template.filename)
        where = f"{filename}:{line}" if line else filename
        message = getattr(error, "message", None) or str(error)
        if isinstance(error, jinja2.UndefinedError):
            return PromptTemplateError(f"prompt template {where}: unknown variable: {message}")
        return PromptTemplateError(f"prompt template {where}: {type(error).__name__}: {message}")

    def render(self, name: str, values: dict[str, Any]) -> str:
        """Render template ``name`` with ``values``; surrounding whitespace stripped."""
        template = self.load(name)
        try:
            return template.render(values).strip()
        except jinja2.TemplateError as error:
            raise self._fail(template, error) from None

    def module(self, name: str, values: dict[str, Any]) -> tuple[str, dict[str, Any]]:
        """Render ``name`` and also return the variables it sets at top level (``{% set %}``)."""
        template = self.load(name)
        try:
            try:
                module = template.make_module(values)
            except jinja2.TemplateError:
                self.env.handle_exception()  # re-raises with template lines, as render() does
        except jinja2.TemplateError as error:
            raise self._fail(template, error) from None
        exported = {key: getattr(module, key) for key in dir(module) if not key.startswith("_")}
        return str(module).strip(), exported

    def security_template(self, variant: str) -> str:
        """The file name of security-prefix ``variant``; a clear error for a bad or unknown name."""
        if not _VARIANT_NAME.match(variant):
            raise PromptTemplateError(
                f"security prefix {variant!r} is not a valid variant name (letters, digits, '_', '-', '.')"
            )
        name = f"{SECURITY_FOLDER}/{variant}.j2"
        if name not in self._cache:
            try:
                self.env.get_template(name)
            except jinja2.TemplateNotFound:
                raise PromptTemplateError(
                    f"security prefix {variant!r}: no template {name!r} in {' or '.join(self.folders)}; "
                    f"variants found: {', '.join(self.variants()) or 'none'}"
                ) from None
            except jinja2.TemplateSyntaxError:
                pass  # load() reports it with the file and line
        return name

    def variants(self) -> list[str]:
        """Every security-prefix variant visible through the search path."""
        found = set()
        for folder in self.folders:
            for path in Path(folder, SECURITY_FOLDER).glob("*.j2"):
                found.add(path.stem)
        return sorted(found)
