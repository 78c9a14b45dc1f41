"""Names of what a run folder holds, for the modules that write them and those that read them.

Its own module so that the run folder (:mod:`safeembodai_core.ablation.run_folder`, which
writes the bag marker) and the runner (:mod:`safeembodai_core.runner`, which reads it) need not
import each other.
"""

from __future__ import annotations

#: A run folder whose ``bags/`` holds this file records a ROS 2 bag per trial as it ends (its text:
#: the storage, ``mcap`` or ``sqlite3``); ``ablate --bags`` writes it.
BAGS_DIR = "bags"
BAG_STORAGE_FILE = "storage"


def trial_file_name(trial_id: str) -> str:
    """A trial's id as one file name (``MO/safeembodai/attack/3`` -> ``MO__safeembodai__attack__3``): its
    picture, its bag and its exported bag are named so."""
    return trial_id.replace("/", "__")
