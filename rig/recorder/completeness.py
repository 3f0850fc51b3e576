"""What an incomplete recording lacks: a truncated file (a killed run) or a run that stopped early."""
from __future__ import annotations

import json

from rig.recorder import schemas as S
from rig.recorder.reader import Recording


def _requested(rec: Recording, key: str) -> float | None:
    """The run's requested ``cycles`` or ``duration`` (s) from its metadata (None: not given)."""
    value = rec.metadata.get(S.RIG_METADATA, {}).get(key)
    return None if value is None else json.loads(value)


def _ranges(numbers: list[int]) -> str:
    """``1-3, 7`` for [1, 2, 3, 7]."""
    runs: list[list[int]] = []
    for n in sorted(numbers):
        if runs and n == runs[-1][-1] + 1:
            runs[-1].append(n)
        else:
            runs.append([n])
    return ", ".join(str(r[0]) if len(r) == 1 else f"{r[0]}-{r[-1]}" for r in runs)


def losses(rec: Recording) -> list[str]:
    """Sentences naming why ``rec`` is incomplete and what it lacks; [] for a complete recording."""
    if rec.complete:
        return []
    out = list(rec.problems)
    if rec.truncated and rec.data_whole:
        out.append("nothing of the run is lost: every message up to the file's data end was read"
                   + ("" if rec.end else "; the run's end record is not in it"))
    elif rec.truncated:
        out.append("lost: the messages after the last whole chunk, the summary"
                   + (" (the run's end record was read)" if rec.end else " and the run's end record"))
    out.append(f"data ends at {rec.last_time:.3f} s of simulation time")
    cycles, duration = _requested(rec, "cycles"), _requested(rec, "duration")
    if cycles is not None and len(rec.curves) < cycles:
        out.append(f"{len(rec.curves)} of {cycles} requested curves recorded; the other {cycles - len(rec.curves)} "
                   f"are not in the file")
    elif duration is not None and rec.last_time < duration:
        out.append(f"{rec.last_time:.3f} of {duration:g} s requested recorded")
    unmatched = {c.number for c in rec.curves} - {int(r["number"]) for r in rec.results if "number" in r}
    if unmatched:
        out.append(f"no result for curve(s) {_ranges(list(unmatched))}")
    if not rec.statistics:
        out.append("no device statistics recorded (the host reads them at the end of a run)")
    return out
