"""Solver benchmarks as user commands: work–precision charts and stability maps (``rig bench …``)."""
