"""``safeembodai_core``'s lazy exports name the module that defines each, and ``__version__`` is the installed
distribution's (never a second copy of pyproject's)."""

from __future__ import annotations

from importlib.metadata import version

import safeembodai_core


def test_every_lazy_export_names_its_defining_module():
    for name, module in safeembodai_core._EXPORTS.items():
        value = getattr(safeembodai_core, name)
        if name == "hookimpl":  # pluggy's marker, made in hookspecs
            assert module == "hookspecs"
            continue
        assert value.__module__ == f"safeembodai_core.{module}", (name, module, value.__module__)


def test_the_version_is_the_installed_distributions():
    assert safeembodai_core.__version__ == version("safeembodai")
    assert "__version__ =" not in (safeembodai_core.__file__ and open(safeembodai_core.__file__).read())
