"""Virtual test rig for mechanism experiments (host side: plants, solvers, scenes, recorder, analysis, CLI)."""

__version__ = "0.1.0"
