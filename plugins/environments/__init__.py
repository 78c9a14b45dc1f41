"""Environment plugins: the worlds a robot is tested in."""
