"""Where rig may write: output files and directories checked before any work starts (README: "rig replaces its own
outputs but never overwrites another file").

A file is replaced only when it is new, empty, or of the kind rig writes there (its first bytes, ``magic``). A
directory is written into only when it is new, empty, or one rig wrote before: rig leaves the marker file
:data:`MARK` in every output directory it uses (a report of an earlier rig also counts), so a directory holding a
user's files is never filled with rig's.
Errors are :class:`UsageError` (exit status 2) naming the path and why, in plain words.
"""
from __future__ import annotations

import errno
import os
import tempfile
from pathlib import Path
from typing import Callable

MARK = ".mechrig"        # in every directory rig writes into
MARK_TEXT = "mechrig writes its outputs here and may replace them; delete this file to keep rig out\n"
#: files whose first bytes show a directory was rig's before it left :data:`MARK` (reports of earlier versions)
RIG_MADE = {"report.html": b"<!DOCTYPE html><html><head><meta charset='utf-8'><title>Rig report:",
            "report.md": b"# Rig report:"}
PNG_MAGIC, JSON_START = b"\x89PNG\r\n\x1a\n", b"{"
#: first bytes of the CAN trace formats rig exports (python-can's writers; MF4 through asammdf)
TRACE_MAGIC = {".asc": b"date ", ".blf": b"LOGG", ".log": b"(", ".trc": b";$FILEVERSION", ".mf4": b"MDF "}


class UsageError(Exception):
    """A command-line argument rig cannot use, e.g. an output path it may not write (exit status 2)."""


def _nearest_existing(path: Path) -> Path:
    path = Path(os.path.abspath(path))
    while not path.exists() and path != path.parent:
        path = path.parent
    return path


def _creatable(path: Path, fail: Callable[[str], None]) -> None:
    """``fail`` unless the missing ``path`` can be made: its nearest existing ancestor is a writable directory."""
    base = _nearest_existing(path)
    if not base.is_dir():
        fail(f"{base} is a file, not a directory")
    if not os.access(base, os.W_OK | os.X_OK):
        fail(f"permission denied (cannot create files in {base})")
    try:                              # root passes os.access; a read-only or virtual file system does not take files
        with tempfile.TemporaryFile(dir=base):
            pass
    except OSError as exc:            # a virtual file system (/proc) answers "no such file" for the folder it has
        why = ("it is a virtual or read-only file system that takes no new files" if exc.errno in
               (errno.ENOENT, errno.EROFS, errno.EOPNOTSUPP) else (exc.strerror or str(exc)).lower())
        fail(f"cannot create files in {base} ({why})")


def writable_file(path: Path, what: str, magic: bytes | None = None) -> None:
    """A :class:`UsageError` naming ``path`` unless rig may write the file ``what`` there: not a directory,
    creatable or writable, and an existing file only when it is empty or — given ``magic``, the first bytes of that
    kind of file — of that kind (rig replaces its own outputs, never another file; without ``magic`` an existing
    non-empty file is never replaced)."""
    path = Path(path)

    def fail(why: str) -> None:
        raise UsageError(f"cannot write the {what} to {path}: {why}")
    if path.is_dir():
        fail("it is a directory")
    if not path.exists():
        _creatable(path.parent, fail)
    else:
        try:
            with path.open("rb") as f:
                head = f.read(len(magic) if magic else 1)
        except OSError as exc:
            fail((exc.strerror or str(exc)).lower())
        if head and (magic is None or not magic.startswith(head)):     # empty, or a (possibly cut) file of that kind
            fail(f"it exists and is not a {what} file rig wrote (rig does not overwrite other files)")
        if not os.access(path, os.W_OK):
            fail("permission denied")
    if magic == PNG_MAGIC and path.suffix.lower() != ".png":    # matplotlib takes the format from the name
        fail(f"a chart is a PNG file, its name must end in .png (e.g. {path.with_suffix('.png')})")


def recording_file(path: Path) -> Path | None:
    """Check the output recording ``path`` of ``rig run``/``rig record`` (:func:`writable_file`, then its name:
    a recording is an MCAP file, ``*.mcap`` — ``-o x.txt`` would write MCAP bytes under a name that says text);
    returns the outermost folder rig will create for it (:func:`new_folder`), None when its folder exists."""
    from rig.recorder.salvage import MCAP_MAGIC
    path = Path(path)
    writable_file(path, "recording", MCAP_MAGIC)
    if path.suffix.lower() != ".mcap":
        raise UsageError(f"cannot write the recording to {path}: a recording is an MCAP file, its name must end in "
                         f".mcap (e.g. {path.with_suffix('.mcap') if path.suffix else path.with_name(path.name + '.mcap')})")
    return new_folder(path)


def new_folder(path: Path) -> Path | None:
    """The outermost folder that writing the file ``path`` will create (its folder and any missing above it), None
    when its folder exists."""
    folder = Path(os.path.abspath(path)).parent
    if folder.exists():
        return None
    while not folder.parent.exists():
        folder = folder.parent
    return folder


def writable_dir(path: Path, what: str, shared: bool = False, hint: str = "") -> None:
    """A :class:`UsageError` naming ``path`` unless it is, or can become, a writable directory rig may fill: new,
    empty, or marked as rig's (:data:`MARK`); ``shared``: a directory rig puts only individually checked files
    into (:func:`writable_file`), which may hold anything else. ``hint``: how the command chooses another."""
    path = Path(path)

    def fail(why: str) -> None:
        raise UsageError(f"cannot write the {what} to {path}: {why}")
    if not path.exists():
        _creatable(path, fail)
        return
    if not path.is_dir():
        fail("it exists and is not a directory")
    if not os.access(path, os.W_OK | os.X_OK):
        fail("permission denied")
    if not shared and not _rig_made(path) and any(path.iterdir()):
        held = sorted(p.name for p in path.iterdir())
        fail(f"it already holds other files ({', '.join(held[:3])}{', …' if len(held) > 3 else ''}) and is not a "
             f"directory rig filled before (it leaves {MARK} there); rig writes into a new or empty directory, or one "
             "it filled before: choose another" + (f" ({hint})" if hint else ""))


def file_parent(path: Path) -> Path:
    """Make the directory of the output file ``path`` (checked by :func:`writable_file`); returns ``path``."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    return path


def _rig_made(path: Path) -> bool:
    """Whether rig wrote into directory ``path`` before: its marker, or a report of an earlier rig."""
    if (path / MARK).exists():
        return True
    for name, head in RIG_MADE.items():
        try:
            with open(path / name, "rb") as f:
                if f.read(len(head)) == head:
                    return True
        except OSError:
            continue
    return False


def clear_previous(out: Path, manifest: str,
                   unlisted: Callable[[Path], set[str]] = lambda out: set()) -> dict[str, int]:
    """Remove what an earlier run of a command wrote into ``out`` (the names in its ``manifest`` file; without one, in a
    directory marked as rig's, ``unlisted(out)``: what an older rig wrote there), so that no figure or table of
    another run is left beside this one's; return the files that stay, with their modification times (ns), for
    :func:`list_written`."""
    listed = out / manifest
    if listed.exists():
        names = set(listed.read_text(encoding="utf-8").split())
    elif (out / MARK).exists():
        names = unlisted(out)
    else:
        names = set()
    for name in names:
        if "/" not in name and name not in (MARK, manifest):
            (out / name).unlink(missing_ok=True)
    return {p.name: p.stat().st_mtime_ns for p in out.iterdir() if p.is_file()}


def list_written(out: Path, manifest: str, before: dict[str, int]) -> None:
    """Write the ``manifest`` of ``out``: the files written since :func:`clear_previous` returned ``before``."""
    written = sorted(p.name for p in out.iterdir()
                     if p.is_file() and not p.name.startswith(".") and before.get(p.name) != p.stat().st_mtime_ns)
    (out / manifest).write_text("".join(f"{name}\n" for name in written), encoding="utf-8")


def claim_dir(path: Path) -> Path:
    """Make the output directory ``path`` (checked by :func:`writable_dir`) and mark it as rig's."""
    path = Path(path)
    path.mkdir(parents=True, exist_ok=True)
    mark = path / MARK
    if not mark.exists():
        mark.write_text(MARK_TEXT)
    return path
