"""``mock``: the offline simulated pilot (work in progress, issue 4)."""
