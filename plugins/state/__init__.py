"""State-store plugins: where step records and the reference state R_{i-1} live."""
