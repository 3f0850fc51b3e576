"""The fidelity choices that ran level 2 to decide (:func:`rig.fidelity.choose`), kept on disk between commands.

A key holds everything the choice depends on: the scene's content, the plant kind, the forced level, the
work–precision data (every CSV's bytes) and the rig's own source (every ``rig/**/*.py``: the models, solvers and
checks), with numpy's, scipy's and numba's versions — a change to any gives a new key. The entries are small JSON
files in ``~/.cache/mechrig/fidelity`` (``MECHRIG_CACHE``), written atomically; one that does not read is computed
again. ``MECHRIG_FIDELITY_CACHE=0`` turns the cache off (the test suite does: its tests replace the checks).
"""
from __future__ import annotations

import hashlib
import json
import logging
import os
import threading
from functools import lru_cache
from pathlib import Path
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from rig.scene import Scene

log = logging.getLogger(__name__)
SOURCE = Path(__file__).resolve().parent


@lru_cache(maxsize=None)
def _code_digest() -> bytes:
    """The rig's source and the numeric libraries' versions, hashed once per process."""
    import numba
    import numpy
    import scipy
    h = hashlib.sha256(f"{numpy.__version__} {scipy.__version__} {numba.__version__}".encode())
    for path in sorted(SOURCE.rglob("*.py")):
        h.update(str(path.relative_to(SOURCE)).encode() + b"\0" + path.read_bytes())
    return h.digest()


def _folder() -> Path:
    return Path(os.environ.get("MECHRIG_CACHE") or Path.home() / ".cache" / "mechrig") / "fidelity"


def key(scene: "Scene", plant: str, forced: int | None, data: Path) -> str | None:
    """The entry's name for a choice (None: the cache is off)."""
    if os.environ.get("MECHRIG_FIDELITY_CACHE", "1") == "0":
        return None
    h = hashlib.sha256(_code_digest())
    h.update(f"{plant}\0{forced!r}\0".encode() + scene.content.encode())
    for path in sorted(Path(data).glob("*.csv")) if Path(data).is_dir() else ():
        h.update(path.name.encode() + b"\0" + path.read_bytes())
    return h.hexdigest()[:32]


def read(name: str | None) -> dict | None:
    """The kept choice ``name`` (the fields of a :class:`rig.fidelity.Fidelity`), if there is one that reads."""
    if name is None:
        return None
    path = _folder() / f"{name}.json"
    try:
        kept = json.loads(path.read_text(encoding="utf-8"))
    except FileNotFoundError:
        return None
    except (OSError, ValueError, RecursionError) as exc:         # damaged, or not ours
        log.debug("fidelity cache %s does not read (%s): computed again", path, exc)
        return None
    return kept if isinstance(kept, dict) else None


def write(name: str | None, fields: dict) -> None:
    """Keep a choice's ``fields`` (JSON) as ``name`` (nothing when the cache is off or its folder cannot be
    written)."""
    if name is None:
        return
    folder = _folder()
    try:
        folder.mkdir(parents=True, exist_ok=True)
        tmp = folder / f"{name}.{os.getpid()}.{threading.get_ident()}.tmp"
        tmp.write_text(json.dumps(fields), encoding="utf-8")
        os.replace(tmp, folder / f"{name}.json")            # atomic: parallel writers see whole files only
    except OSError as exc:
        log.debug("fidelity cache %s not written (%s)", folder, exc)
