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


def nothing_recorded(rec: Recording) -> str | None:
    """Why a recording read with ``allow_partial`` holds nothing to report or analyse, in words: no message, or none
    of rig's (a file another program wrote: no rig metadata, no scene, no rig topic); None when it holds some."""
    if not rec.message_counts:
        return "the recording holds no message: " + "; ".join(rec.problems or ["no message was written"])
    ours = [t for t in rec.message_counts if S.is_rig_topic(t)]
    if ours or S.RIG_METADATA in rec.metadata or rec.scene_text is not None:
        return None
    topics = sorted(rec.message_counts)
    return (f"not a rig recording: no rig metadata, no scene and none of rig's topics (it holds "
            f"{', '.join(topics[:5])}{', …' if len(topics) > 5 else ''})")


def file_problem(rec: Recording) -> str:
    """What is wrong with a truncated recording's file, in a few words: damaged, cut short, or both."""
    cut = "truncated (run killed or file cut)"
    if not rec.damaged:
        return f"file {cut}"
    return "file damaged" + ("" if rec.read_to_data_end or rec.data_whole else f" and {cut}")


def all_counted(rec: Recording) -> bool:
    """Whether the file's run end record (written when the recorder closed) counts exactly the messages read, with
    no part lost: a file cut just after its last chunk lacks only its index (summary, footer)."""
    try:
        written = int(rec.end.get("messages", ""))
    except ValueError:
        return False
    return not rec.lost and written == sum(rec.message_counts.values())


def tail_lost(rec: Recording) -> bool:
    """Whether messages after the last one read may be missing (reading stopped at a cut before the data end, and
    the run's end record does not show that everything was read)."""
    return rec.truncated and not rec.read_to_data_end and not all_counted(rec)


def losses(rec: Recording) -> list[str]:
    """Sentences naming why ``rec`` is incomplete and what it lacks; [] for a complete recording."""
    if rec.complete:
        return []
    out = list(rec.problems)
    if rec.truncated and rec.data_whole:
        out.append("nothing of the run is lost: every message up to the file's data end was read"
                   + ("" if rec.end else "; the run's end record is not in it"))
    elif rec.truncated and all_counted(rec):
        out.append(f"nothing of the run is lost: its end record counts {rec.end['messages']} messages and all were "
                   "read; the file lacks only its index after the data (summary, footer)")
    elif rec.truncated and rec.read_to_data_end:
        out.append(f"lost: only what the damaged part{'s' if len(rec.lost) > 1 else ''} named above held; every "
                   "other record up to the file's data end was read"
                   + (" (the run's end record too)" if rec.end else "; the run's end record is not in it"))
    elif rec.truncated:
        cut = any(part.cut for part in rec.lost)
        out.append(f"lost: {'the cut chunk named above' if cut else 'the messages after the last whole chunk'}, "
                   "the summary"
                   + (" (the run's end record was read)" if rec.end else " and the run's end record"))
    out.append(f"data ends at {rec.last_time:.3f} s of simulation time")
    cycles, duration = _requested(rec, "cycles"), _requested(rec, "duration")
    if cycles is not None and len(rec.curves) < cycles:
        numbers = {c.number for c in rec.curves}
        top = min(max(numbers, default=0), cycles)
        missing = [_ranges(sorted(set(range(1, top + 1)) - numbers))] if len(numbers) < top else []
        missing += [str(cycles) if top + 1 == cycles else f"{top + 1}-{cycles}"] if top < cycles else []
        plural = "s" if cycles - len(rec.curves) > 1 else ""
        named = f" (curve{plural} {', '.join(missing)})" if rec.lost else ""
        out.append(f"{len(rec.curves)} of {cycles} requested curves recorded; the other {cycles - len(rec.curves)} "
                   f"are not in the file{named}")
    elif duration is not None and rec.last_time < duration:
        out.append(f"{rec.last_time:.3f} of {duration:g} s requested recorded")
    unmatched = {c.number for c in rec.curves} - {int(r["number"]) for r in rec.results if "number" in r}
    if unmatched:
        out.append(f"no result for curve(s) {_ranges(list(unmatched))}")
    if not rec.statistics and not rec.serial_link_off:       # (a stand or a lab reads none)
        out.append("no device statistics recorded (the host reads them at the end of a run)")
    return out
