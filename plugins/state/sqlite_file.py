"""Where a run's ``sqlite`` store lives: the file name the registration, the store's report
queries and ``safeembodai show`` share (a light module: no ``sqlite3``, no ``rich``)."""

from __future__ import annotations

#: the database file in a run folder, when the scenario gives no ``path``
DEFAULT_FILE = "results.sqlite"
