#!/usr/bin/env python3
"""Run a command inside the project's virtual environment, creating it first if needed.

Usage: ``python3 bootstrap.py COMMAND [ARGS...]`` (e.g. ``rig run ...`` or ``pytest``).
Needs only Python >= 3.11. The environment lives in ``.venv/`` and is reinstalled whenever
``pyproject.toml`` changes (a hash of it is kept in ``.venv/.installed``).
"""
from __future__ import annotations

import hashlib
import os
import subprocess
import sys
import venv
from pathlib import Path

ROOT = Path(__file__).resolve().parent
VENV = ROOT / ".venv"
BIN = VENV / ("Scripts" if os.name == "nt" else "bin")
STAMP = VENV / ".installed"


def ensure_environment() -> None:
    """Create ``.venv`` and install the project with its test extras when out of date."""
    if sys.version_info < (3, 11):
        sys.exit(f"bootstrap: Python >= 3.11 is required, this is {sys.version.split()[0]}")
    digest = hashlib.sha256((ROOT / "pyproject.toml").read_bytes()).hexdigest()
    if STAMP.exists() and STAMP.read_text().strip() == digest:
        return
    if not (BIN / "python").exists():
        print("bootstrap: creating .venv", file=sys.stderr)
        venv.EnvBuilder(with_pip=True).create(VENV)
    print("bootstrap: installing the project and its dependencies into .venv", file=sys.stderr)
    pip = [str(BIN / "python"), "-m", "pip", "install", "--disable-pip-version-check", "-q"]
    subprocess.run(pip + ["-e", f"{ROOT}[test]"], check=True)
    STAMP.write_text(digest)


def main() -> None:
    if len(sys.argv) < 2:
        sys.exit(__doc__)
    ensure_environment()
    command, *args = sys.argv[1:]
    exe = BIN / command
    argv = [str(exe) if exe.exists() else command, *args]
    os.environ["PATH"] = f"{BIN}{os.pathsep}{os.environ.get('PATH', '')}"
    os.environ.setdefault("MPLBACKEND", "Agg")
    os.chdir(ROOT)
    os.execvp(argv[0], argv)


if __name__ == "__main__":
    main()
