"""``sqlite``: a SQLite state store (work in progress, issue 5)."""
