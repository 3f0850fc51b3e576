"""Bounds of what a scene and the command line take, beyond which no machine lies (a light module: the command line
imports it to build its parser)."""
from __future__ import annotations

HUGE = 1e30          # the largest magnitude of a scene quantity in SI (larger ones overflow the models' arithmetic)
MAX_CYCLES = 10**9   # machine cycles a run takes ([scene] cycles, --cycles: 10^9 at 150 rpm are 13 years)
MAX_DURATION = 1e9   # s of simulated time a run takes ([scene] duration, max_time: 31 years; 1e20 s ran until killed)
