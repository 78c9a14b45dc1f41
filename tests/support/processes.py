"""The processes of this machine a test started, found by what their command line names."""

from __future__ import annotations

import os
from pathlib import Path


def processes_naming(marker: str) -> list[str]:
    """Live (not zombie) processes other than this one whose command line names ``marker``: pid and command."""
    found = []
    for entry in Path("/proc").iterdir():
        if not entry.name.isdigit() or entry.name == str(os.getpid()):
            continue
        try:
            command = (entry / "cmdline").read_bytes().replace(b"\0", b" ").decode(errors="replace")
            state = (entry / "stat").read_text().rsplit(")", 1)[1].split()[0]
        except (OSError, IndexError):
            continue
        if marker in command and state != "Z":
            found.append(f"{entry.name}: {command[:120]}")
    return found
