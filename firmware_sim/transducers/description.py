"""Device descriptions (``data/devices/*.toml``) and the registry mapping a ``type`` to a class.

A description file holds one table ``[transducer]``: ``type`` picks the behaviour class, every other
key is validated against that class's ``SCHEMA`` (explicit units, see :mod:`rig.scene`). Overrides
(e.g. from a scene's ``[transducers.NAME]``) use the same key spellings and replace file values.
"""
from __future__ import annotations

import tomllib
from pathlib import Path
from typing import Any, Callable, Mapping

import numpy as np

from rig.scene import Field, Scene, SceneError, read_table

DEVICES_DIR = Path(__file__).resolve().parents[2] / "data" / "devices"

REGISTRY: dict[str, type] = {}

_UNSET = object()


def register(type_name: str) -> Callable[[type], type]:
    """Class decorator: make ``type = "<type_name>"`` in a description build this class."""
    def wrap(cls: type) -> type:
        if type_name in REGISTRY:
            raise ValueError(f"transducer type {type_name!r} registered twice")
        REGISTRY[type_name] = cls
        cls.TYPE = type_name
        return cls
    return wrap


def is_path(name_or_path: str | Path) -> bool:
    """True for a description file path (``devs/force.toml``), False for a name looked up in ``data/devices``."""
    p = Path(name_or_path)
    return p.suffix == ".toml" or p.parent != Path(".")


def described(scene: Scene, written: str) -> str:
    """A device description as a scene names it, as the runner opens it: a name (``burster_8411``, in
    data/devices) as it is, a path relative to the scene file's folder (not the current directory) made whole."""
    return str(scene.file(written)) if is_path(written) else written


def resolve_path(name_or_path: str | Path) -> Path:
    """A description name (``"burster_8411"``, looked up in ``data/devices``) or a file path."""
    return Path(name_or_path) if is_path(name_or_path) else DEVICES_DIR / f"{name_or_path}.toml"


def read_description(path: Path) -> dict[str, Any]:
    """The raw ``[transducer]`` table of a description file."""
    try:
        data = tomllib.loads(path.read_text(encoding="utf-8"))
    except OSError as exc:
        known = ", ".join(sorted(q.stem for q in DEVICES_DIR.glob("*.toml")))
        raise SceneError(f"cannot read device description {path}: {exc.strerror} (known: {known})") from None
    except tomllib.TOMLDecodeError as exc:
        raise SceneError(f"{path}: not valid TOML: {exc}") from None
    table = data.get("transducer")
    if not isinstance(table, dict):
        raise SceneError(f"{path}: missing table [transducer]")
    return table


def validate(table: Mapping[str, Any], overrides: Mapping[str, Any], schema: Mapping[str, Field],
             where: str) -> dict[str, Any]:
    """File values merged with overrides, both validated against ``schema``; returns SI values."""
    base = read_table(table, schema, where)
    optional = {name: Field(f.unit, _UNSET, f.doc) for name, f in schema.items()}
    extra = read_table(overrides, optional, f"{where} (overrides)")
    base.update({k: v for k, v in extra.items() if v is not _UNSET})
    return base


def load_transducer(name_or_path: str | Path, rng: np.random.Generator, **overrides: Any) -> Any:
    """Build the transducer described by a device file, drawing its individual errors from ``rng``.

    ``overrides`` replace description keys (same spellings, e.g. ``preload="-25 N"``); the keys
    ``errors_enabled`` and ``dynamics_enabled`` (bool) switch the error sources / the dynamics.
    """
    if not isinstance(rng, np.random.Generator):
        raise TypeError(f"load_transducer needs a numpy.random.Generator, got {type(rng).__name__}")
    path = resolve_path(name_or_path)
    table = dict(read_description(path))
    type_name = table.pop("type", None)
    if type_name not in REGISTRY:
        raise SceneError(f"{path} [transducer]: type {type_name!r} is not one of {sorted(REGISTRY)}")
    cls = REGISTRY[type_name]
    flags = {k: overrides.pop(k) for k in ("errors_enabled", "dynamics_enabled") if k in overrides}
    for key, value in flags.items():
        if not isinstance(value, (bool, np.bool_)):     # "false" is a string, and bool("false") is True
            raise SceneError(f"{path} [transducer]: override {key!r} must be true or false (no quotes), got {value!r}")
    params = validate(table, overrides, cls.SCHEMA, f"{path} [transducer]")
    return cls(params, rng, name=path.stem, **flags)
