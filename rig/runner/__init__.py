"""The rig runner: scene → plant → transducers → device → links → host → MCAP recorder.

* :mod:`rig.runner.config` reads the runner's scene sections;
* :mod:`rig.runner.plants` builds a plant by name;
* :mod:`rig.runner.machine` is the simulated machine side (plant, transducers, DigiForce, CAN node,
  serial device) — what ``rig serve`` runs;
* :mod:`rig.runner.host` is the host side (CAN and serial drivers, theory, recorder) — what
  ``rig record`` runs;
* :mod:`rig.runner.session` runs both in one process (``rig run``) or either alone.
"""
from rig.runner.config import RunConfig, read_config
from rig.runner.session import RunSummary, record_scene, run_scene, serve_scene

__all__ = ["RunConfig", "RunSummary", "read_config", "record_scene", "run_scene", "serve_scene"]
