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
