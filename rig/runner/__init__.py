"""The rig runner: scene → plant → transducers → device → links → host → MCAP recorder.

* :mod:`rig.runner.config` reads the runner's scene sections;
* :mod:`rig.runner.plants` builds a plant by name;
* :mod:`rig.runner.machine` is the simulated machine side (plant, transducers, DigiForce, CAN node,
  serial device) — what ``rig serve`` runs;
* :mod:`rig.runner.host` is the host side (CAN and serial drivers, theory, recorder) — what
  ``rig record`` runs;
* :mod:`rig.runner.session` runs both in one process (``rig run``) or either alone;
* :mod:`rig.runner.errors` holds why a run could not complete.

The names below are imported on first use (:mod:`rig.lazy`).
"""
from rig.lazy import exports

_WHERE = {"RunConfig": "rig.runner.config", "read_config": "rig.runner.config",
          **dict.fromkeys(("RunSummary", "record_scene", "run_scene", "serve_scene"), "rig.runner.session")}
__all__ = list(_WHERE)
__getattr__ = exports(__name__, _WHERE)
