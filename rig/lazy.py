"""Lazy package exports (PEP 562): a package names what it exports and from which module, and a name is imported
when it is first used — so that importing one light module of a package (its errors, a table of names) does not
import the package's heavy modules (the CAN stack, scipy.signal, the recorder)."""
from __future__ import annotations

import importlib
from typing import Any, Callable


def exports(package: str, where: dict[str, str]) -> Callable[[str], Any]:
    """A module ``__getattr__`` for ``package`` that imports each name of ``where`` (name → module) on first use."""
    def __getattr__(name: str) -> Any:
        if name not in where:
            raise AttributeError(f"module {package!r} has no attribute {name!r}")
        return getattr(importlib.import_module(where[name]), name)
    return __getattr__
