#!/usr/bin/env python3
"""Run a command inside the project's virtual environment, creating it first if needed.

Usage: ``python3 bootstrap.py COMMAND [ARGS...]`` (e.g. ``rig run ...`` or ``pytest``); the command runs in the
caller's directory (``pytest`` in the project's).
Needs only Python >= 3.11. The environment lives in ``.venv/`` and is reinstalled whenever
``pyproject.toml`` changes (a hash of it is kept in ``.venv/.installed``); the first time that takes a
few minutes, shown step by step on stderr with pip's progress.
"""
from __future__ import annotations

import hashlib
import os
import subprocess
import sys
import time
import venv
from pathlib import Path

ROOT = Path(__file__).resolve().parent
VENV = ROOT / ".venv"
BIN = VENV / ("Scripts" if os.name == "nt" else "bin")
STAMP = VENV / ".installed"


#: what a first install fetches and how long it takes (about two minutes on a fast connection)
INSTALL_NOTE = ("numpy, scipy, matplotlib, numba + llvmlite, python-can, cantools, asammdf, pint, mcap and their "
                "dependencies (about 700 MB installed): typically 1-3 minutes, less when pip's cache has them")


def say(text: str) -> None:
    print(f"bootstrap: {text}", file=sys.stderr, flush=True)


def ensure_environment() -> None:
    """Create ``.venv`` and install the project with its test extras when out of date, saying what it
    does: one line per step with an estimate, and pip's own progress (its output goes to stderr, so the
    command's stdout stays its own)."""
    if sys.version_info < (3, 11):
        sys.exit(f"bootstrap: Python >= 3.11 is required, this is {sys.version.split()[0]}")
    digest = hashlib.sha256((ROOT / "pyproject.toml").read_bytes()).hexdigest()
    if STAMP.exists() and STAMP.read_text().strip() == digest:
        return
    start = time.monotonic()
    if not (BIN / "python").exists():
        say(f"creating the virtual environment {VENV} with pip (a few seconds)")
        venv.EnvBuilder(with_pip=True).create(VENV)
    else:
        say(f"pyproject.toml changed since {VENV} was set up: updating it")
    say(f"installing mechrig (editable) with {INSTALL_NOTE}; pip reports each package below")
    pip = [str(BIN / "python"), "-m", "pip", "install", "--disable-pip-version-check", "--progress-bar", "on"]
    try:
        to_stderr = sys.stderr.fileno()
    except (AttributeError, OSError, ValueError):
        to_stderr = None
    result = subprocess.run(pip + ["-e", f"{ROOT}[test]"], stdout=to_stderr, check=False)
    if result.returncode != 0:
        sys.exit(f"bootstrap: pip failed (exit status {result.returncode}); its messages are above. "
                 f"Fix the cause (network, proxy, disk space) and run bootstrap.py again")
    STAMP.write_text(digest)
    say(f"environment ready in {time.monotonic() - start:.0f} s; later runs start at once")


def main() -> None:
    if len(sys.argv) < 2:
        sys.exit(__doc__)
    ensure_environment()
    command, *args = sys.argv[1:]
    exe = BIN / command
    argv = [str(exe) if exe.exists() else command, *args]
    os.environ["PATH"] = f"{BIN}{os.pathsep}{os.environ.get('PATH', '')}"
    os.environ.setdefault("MPLBACKEND", "Agg")
    if command == "pytest":          # the project's tests, wherever it is called from
        os.chdir(ROOT)
    os.execvp(argv[0], argv)         # anything else in the caller's directory: its relative paths are the caller's


if __name__ == "__main__":
    main()
