"""``OF``/``SO``/``DO``/``MO``: the paper's four rooms on pybullet (work in progress, issue 3)."""
