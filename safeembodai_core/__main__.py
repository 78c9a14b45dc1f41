"""``python -m safeembodai_core`` is the ``safeembodai`` command."""

from .cli import main

main()
