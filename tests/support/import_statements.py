"""Import statements read with ``ast``: the absolute module a ``from ... import`` names, relative ones resolved."""

from __future__ import annotations

import ast


def imported_from(node: ast.ImportFrom, module: str, is_package: bool) -> str:
    """The absolute name of the module ``node`` imports from, written in ``module`` (a package's
    ``__init__`` when ``is_package``): ``from ..models import X`` in ``a.b.c`` is ``a.models``."""
    if not node.level:
        return node.module or ""
    base = module if is_package else module.rpartition(".")[0]
    for _ in range(node.level - 1):
        base = base.rpartition(".")[0]
    return f"{base}.{node.module}" if node.module else base
