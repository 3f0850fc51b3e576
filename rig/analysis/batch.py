"""Batch analysis: many recordings on an executor → one table (a row per recording) and one report
(``rig analyse``).

Recordings are grouped into tasks (about 8 per worker); each is read with :func:`rig.recorder.read_recording` and analysed with
:func:`rig.analysis.analyse` on a worker; only a small summary comes back (verdict counts, event counts and,
per program and process value, the moments of every curve's value in display units; for a stand or lab
recording its console lines and its numeric key results as values ``stand.<name>`` (dynamic clutch stand) or
``lab.<sheet>.<name>`` (lab sheets)). The combined statistics merge those moments
(:class:`rig.analysis.streaming.Moments`, in the order the recordings were given) per scene and model level:
a start-up and a shock test, or a level-1 and a level-2 run of the machine, are not one population.
Copies of one run (the same scene, seed and wall-clock start: a file copied, or a cut copy of it) count once —
the copy holding the most curves; recordings of one scene made with the same seed repeat one another's values
(the same machines and draws), which the report says.
"""
from __future__ import annotations

import csv
import glob
import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Callable, Sequence

import numpy as np

from rig.analysis.numbers import plural
from rig.analysis.streaming import Moments
from rig.executors import batches

if TYPE_CHECKING:
    from rig.executors import Executor
    from rig.recorder import Recording

STATS = ("n", "mean", "std", "min", "max")
LISTED = 20  # recordings named per list in the report


@dataclass
class RecordingSummary:
    """What one recording holds: its scene and plant, verdict counts, process values {"p<program>.<name>":
    (Moments, display unit)} (a stand's or lab's key results as "stand.<name>" / "lab.<sheet>.<name>"), its summary
    lines, event counts, whether it is complete and why not (``incomplete``: a cut or damaged file, read with
    ``allow_partial`` for what it holds, or a run stopped early), and why it could not be read (``error``: nothing
    in it to analyse)."""

    path: str
    scene: str = ""
    plant: str = ""
    complete: bool = False
    curves: int = 0
    ok: int = 0
    nok: int = 0
    values: dict[str, tuple[Moments, str]] = field(default_factory=dict)
    events: dict[str, int] = field(default_factory=dict)
    stand: list[str] = field(default_factory=list)
    error: str = ""
    level: str = ""
    incomplete: str = ""
    not_recorded: int = 0      # curves the unit judged whose samples were not recorded (frames incomplete): in ok / nok
    seed: str = ""
    started: str = ""          # the run's wall-clock start (ns, from its metadata): with scene and seed, which run
    copy_of: str = ""          # the path of another copy of the same run, counted instead of this one
    machine: dict[str, str] = field(default_factory=dict)     # the scene's values but the run's (RUN_SETTING)
    variant: str = ""          # set by analyse_batch where recordings of one scene name describe different machines
    limits: dict[str, tuple[float | None, float | None]] = field(default_factory=dict)  # program limits, display units

    @property
    def group(self) -> str:
        """The population its values belong to: scene and model level (``pin_insertion L1``), and the machine's own
        values where recordings of that scene name describe different machines (``… (plant.F_c = 62 N)``)."""
        return (f"{self.scene or 'unknown scene'}" + (f" L{self.level}" if self.level not in ("", "null") else "")
                + (f" ({self.variant})" if self.variant else ""))


#: scene keys that set the run, not the machine: recordings that differ only in these are one population
RUN_SETTING = {"scene": ("seed", "cycles", "duration", "name", "description", "mode", "chunk"), "recording": None}


def machine_of(scene_text: str) -> dict[str, str]:
    """The recorded scene's values that describe the machine (dotted key → value as written), without
    :data:`RUN_SETTING`; {} for a recording without its scene or with one that does not parse."""
    data = _scene_data(scene_text)
    out: dict[str, str] = {}

    def walk(node: object, key: str) -> None:
        if isinstance(node, dict):
            for k, v in node.items():
                walk(v, f"{key}.{k}" if key else k)
        elif isinstance(node, list):          # arrays (of tables): item by item, so each value compares by value
            for i, v in enumerate(node):
                walk(v, f"{key}[{i}]")
            if not node:
                out[key] = "[]"
        else:
            out[key] = repr(node)

    for section, value in data.items():
        if section in RUN_SETTING and RUN_SETTING[section] is None:
            continue
        if isinstance(value, dict) and section in RUN_SETTING:
            value = {k: v for k, v in value.items() if k not in RUN_SETTING[section]}
        walk(value, section)
    return out


def expand(patterns: Sequence[str]) -> list[Path]:
    """Paths named by ``patterns`` (globs, ``**`` recursive; a folder: the ``*.mcap`` files under it, at any
    depth, the extension in any case: ``RUN.MCAP`` too), sorted per pattern, each once, absolute (a worker of a
    cluster opens them from its own folder); a
    pattern that matches nothing is a ValueError naming it."""
    out: dict[Path, None] = {}
    for pattern in patterns:
        hits = sorted(glob.glob(pattern, recursive=True))
        if not hits:
            raise ValueError(f"no recording matches {pattern!r}")
        for hit in (Path(h).absolute() for h in hits):
            if hit.is_dir():
                out.update((p, None) for p in sorted(hit.rglob("*")) if p.suffix.lower() == ".mcap" and p.is_file())
            elif hit.is_file():
                out[hit] = None
    if not out:
        raise ValueError(f"no recording files in {', '.join(patterns)}")
    return list(out)


def _value_moments(rec: "Recording", units: dict) -> tuple[dict[str, tuple[Moments, str]], dict[str, tuple]]:
    """Per program and process value the moments of its finite values in display units (every curve counts,
    also in sets too small for the per-set statistics), and its program's limits in that unit (where it has any)."""
    from rig.analysis.sets import by_program, limits_from_program, process_values
    out, limits = {}, {}
    for program, results in by_program(rec.results).items():
        bounds = limits_from_program(rec.programs.get(program))
        for name, v in process_values(results).items():
            u = units[program].value(name)
            shown = np.asarray(u(v), dtype=float)
            shown = shown[np.isfinite(shown)]
            if shown.size:
                out[f"p{program}.{name}"] = (Moments.of_block(shown[:, None]), u.label)
                if name in bounds:
                    limits[f"p{program}.{name}"] = (u(bounds[name][0]), u(bounds[name][1]))
    return out, limits


def summarise(path: Path) -> RecordingSummary:
    """Read and analyse one recording (a task)."""
    from rig.analysis import analyse
    from rig.analysis.stand_summary import stand_summary
    from rig.recorder import RecordingError, read_recording
    from rig.recorder.completeness import losses, nothing_recorded
    try:
        rec = read_recording(path, allow_partial=True, can_frames=False)
        empty = nothing_recorded(rec)
        if empty is not None:
            raise RecordingError(f"{path}: {empty}")
        result = analyse(rec)
        values, limits = _value_moments(rec, result["units"])
        summary = stand_summary(rec)
        if summary is not None:
            values.update({k: (Moments.of_block(np.array([[v]])), unit) for k, (v, unit) in summary.values.items()})
    except (RecordingError, OSError, ValueError) as exc:
        text = " ".join(str(exc).split())
        return RecordingSummary(str(path), error=text.removeprefix(f"{path}: "))     # the row names the file
    verdicts = result["verdicts"]
    ok = sum(1 for v in verdicts if v["ok"])
    curves = len({c.number for c in rec.curves} | {v["number"] for v in verdicts})   # a cut run's last curve may
    # have arrived without its result: recorded, not judged (ok + nok < curves; "why incomplete" says which)
    meta = {**_scene_table(rec.scene_text), **rec.metadata.get("rig", {})}   # the metadata, else the scene's words
    return RecordingSummary(str(path), str(meta.get("scene", "")), str(meta.get("plant", "")), rec.complete,
                            curves, ok, len(verdicts) - ok, values, dict(result["events"]),
                            summary.lines if summary is not None else [], level=str(meta.get("fidelity_level", "")),
                            incomplete=" ".join("; ".join(losses(rec)).split()), seed=str(meta.get("seed", "")),
                            started=str(meta.get("wall_clock_start", "")), machine=machine_of(rec.scene_text),
                            not_recorded=len(result["not_recorded"]), limits=limits)


def _scene_table(scene_text: str) -> dict[str, object]:
    """The recorded scene's name, plant and seed ([scene]): what the run's metadata says, for a recording whose
    metadata record was lost ({} without a scene that parses)."""
    table = _scene_data(scene_text).get("scene", {})
    return {("scene" if k == "name" else k): table[k] for k in ("name", "plant", "seed") if k in table} \
        if isinstance(table, dict) else {}


def _scene_data(scene_text: str | None) -> dict:
    """The recorded scene as TOML data; {} for a recording without its scene (None) or with one that does not
    parse (damaged)."""
    import tomllib
    try:
        return tomllib.loads(scene_text) if isinstance(scene_text, str) else {}
    except tomllib.TOMLDecodeError:
        return {}


def summarise_all(paths: list[Path]) -> list[RecordingSummary]:
    """:func:`summarise` of several recordings (one executor task: a short recording takes ~0.1 s)."""
    return [summarise(p) for p in paths]


@dataclass(frozen=True)
class BatchResult:
    """Every recording's summary (in the order given) and the process values merged per population
    (:attr:`RecordingSummary.group`): ``combined[(group, value)] = (Moments, unit)``."""

    recordings: list[RecordingSummary]
    combined: dict[tuple[str, str], tuple[Moments, str]]


def analyse_batch(paths: Sequence[Path], executor: "Executor",
                  progress: Callable[[int], object] = lambda recordings: None) -> BatchResult:
    """:func:`summarise` every path on ``executor`` (``progress(k)`` as each task's ``k`` recordings are read); merge
    the process values per scene and level in path order (units must agree within one)."""
    rows = []
    for part in executor.map(summarise_all, batches(list(paths), executor.workers)):
        rows += part
        progress(len(part))
    _mark_copies(rows)
    _name_variants(rows)
    combined: dict[tuple[str, str], tuple[Moments, str]] = {}
    for row in rows:
        if row.copy_of:
            continue
        for name, (m, unit) in row.values.items():
            key = (row.group, name)
            if key not in combined:
                combined[key] = (m, unit)
                continue
            first = combined[key][1]              # one machine, a unit written otherwise (cm, mm): in the first's
            factor = 1.0 if unit == first else unit_factor(unit, first)
            if not factor > 0.0:
                raise ValueError(f"{row.path}: {name} in {unit!r}, earlier recordings of {row.group} in {first!r}")
            combined[key] = (combined[key][0].merge(m if factor == 1.0 else m.scaled(factor)), first)
    return BatchResult(rows, combined)


def unit_factor(unit: str, to: str) -> float:
    """The factor from display unit ``unit`` to ``to`` ("cm" → "mm": 10); NaN where they are not of one kind (an
    angle's presence counts: 1/min is not rpm, as :func:`rig.units.to_si` says)."""
    from rig.analysis.units import pint_label
    from rig.units import to_si
    try:
        return to_si(f"1 {pint_label(unit)}", pint_label(to))
    except ValueError:
        return math.nan


def _name_variants(rows: list[RecordingSummary]) -> None:
    """Where recordings of one scene name and level describe different machines (their scenes differ beyond the
    run's setting), name each machine by the values that tell them apart: each is its own population."""
    machines: dict[str, dict[tuple, dict[str, str]]] = {}     # group → canonical machine → the first as written
    for row in rows:
        if not row.error and row.machine:
            machines.setdefault(row.group, {}).setdefault(_canonical(row.machine), row.machine)
    for row in rows:                    # a scene lost (or damaged) in its file: which machine is not known, so not pooled
        if not row.error and not row.machine:
            row.variant = "scene lost: machine unknown"
    for group, seen in machines.items():
        if len(seen) < 2:
            continue
        canon = [dict(c) for c in seen]
        keys = sorted({k for m in canon for k in m if len({m.get(k) for m in canon}) > 1},
                      key=lambda k: (not k.startswith("plant"), k))        # the machine's own values first
        shown = 3                             # as few of them as tell every machine apart: the label is the population
        while shown < len(keys) and len({tuple(m.get(k) for k in keys[:shown]) for m in canon}) < len(canon):
            shown += 1
        for row in rows:
            if not row.error and row.machine and row.group == group:
                written = seen[_canonical(row.machine)]       # one label per machine, whatever the units written
                said = [f"{k} = {_plain(written.get(k, 'unset'))}" for k in keys[:shown]]
                row.variant = ", ".join(said) + (f", … ({len(keys) - shown} more)" if len(keys) > shown else "")


def _canonical(machine: dict[str, str]) -> tuple:
    """The machine's values compared by value: a quantity in SI base units to 12 significant digits ("1.89 N/mm" and
    "1890 N/m" are one spring), a number to 12 digits, anything else as written."""
    from rig.units import split_quantity, ureg
    out = []
    for key, value in sorted(machine.items()):
        split = split_quantity(_plain(value))
        if split is not None:
            number, unit = split
            try:
                q = ureg.Quantity(number, unit).to_base_units() if unit else None
            except Exception:  # noqa: BLE001 - pint's parser raises many kinds: compare the text then
                q = False
            if q is None:
                value = f"{number:.12g}"
            elif q is not False:
                value = f"{q.magnitude:.12g} {q.units}"
        out.append((key, value))
    return tuple(out)


def _plain(value: str) -> str:
    """A scene value as written (the quotes of a TOML string dropped)."""
    return value[1:-1] if len(value) > 1 and value[0] == value[-1] and value[0] in "'\"" else value


def _mark_copies(rows: list[RecordingSummary]) -> None:
    """Mark every copy of a run but the one holding the most curves (the first given among equals) as a copy."""
    runs: dict[tuple[str, str, str], list[RecordingSummary]] = {}
    for row in rows:
        if not row.error and row.started:
            runs.setdefault((row.scene, row.seed, row.started), []).append(row)
    for copies in runs.values():
        kept = max(copies, key=lambda r: (r.curves, r.complete))          # max: the first of equals
        for row in copies:
            if row is not kept:
                row.copy_of = kept.path


def shared_seeds(rows: list[RecordingSummary]) -> dict[tuple[str, str], list[RecordingSummary]]:
    """Distinct runs (copies aside) of one scene and model level made with one seed: {(group, seed): runs}, only
    where there are several — their machines and draws are the same, so their values repeat one another."""
    out: dict[tuple[str, str], list[RecordingSummary]] = {}
    for row in rows:
        if not row.error and not row.copy_of and row.seed not in ("", "null"):
            out.setdefault((row.group, row.seed), []).append(row)
    return {key: runs for key, runs in out.items() if len(runs) > 1}


def _stats(m: Moments) -> tuple:
    return m.n, float(m.mean[0]), float(m.std(1)[0]) if m.n > 1 else "", float(m.minimum[0]), float(m.maximum[0])


def write_table(result: BatchResult, path: Path) -> Path:
    """CSV, one row per recording: path, scene, level, plant, complete, why incomplete, curves (recorded, judged or not),
    OK, NOK (judged), judged not recorded (curves whose frames did not all arrive), error, the run it copies, seed,
    population (:attr:`RecordingSummary.group`), a stand's or lab's summary lines (joined by " | ", the console's column
    padding collapsed), then n/mean/std/min/max of every process value (and stand result) any recording has (display
    units, in the header; a value shown in two units gets a column group per unit)."""
    keys = sorted({(k, u) for r in result.recordings for k, (_, u) in r.values.items()})
    names = [k for k, _ in keys]
    twice = {k for k in names if names.count(k) > 1}     # shown in two units: its n columns named by unit too
    path.parent.mkdir(parents=True, exist_ok=True)
    with path.open("w", newline="") as f:
        out = csv.writer(f)
        out.writerow(["recording", "scene", "level", "plant", "complete", "why incomplete", "curves", "ok", "nok",
                      "judged not recorded", "error", "copy of (not counted)", "seed", "population", "stand"]
                     + [f"{k} {s}" + (f" [{u}]" if u and (s != "n" or k in twice) else "")
                        for k, u in keys for s in STATS])
        for r in result.recordings:
            out.writerow([r.path, r.scene, r.level, r.plant, r.complete, r.incomplete, r.curves, r.ok, r.nok,
                          r.not_recorded, r.error, r.copy_of, r.seed, "" if r.error else r.group,
                          " | ".join(" ".join(line.split()) for line in r.stand)]      # no console padding
                         + [x for k, u in keys
                            for x in (_stats(r.values[k][0]) if k in r.values and r.values[k][1] == u else [""] * 5)])
    return path


def report_lines(result: BatchResult, charts: Sequence[tuple[str, str, Sequence[str]]] = ()) -> list[str]:
    """The combined report (Markdown): totals, process values (and stand results) over all recordings, the charts
    (``charts``: population, the PNG's path relative to the report, the values it leaves out; see
    :mod:`rig.analysis.batch_charts`), the stand and lab recordings with their summaries, recordings with NOK curves,
    incomplete ones (with the reason: a cut or damaged file analysed for what it holds, a run stopped early) and
    unreadable ones."""
    recs = result.recordings
    copies = [r for r in recs if r.copy_of]
    read = [r for r in recs if not r.error and not r.copy_of]
    incomplete = [r for r in recs if not r.error and not r.complete]       # copies too: the files are cut
    curves, nok = sum(r.curves for r in read), sum(r.nok for r in read)
    groups = sorted({r.group for r in read})
    lines = [f"# Batch analysis of {plural(len(recs), 'recording')}", "",
             f"{len(read) + len(copies)} read" + (f" ({len(incomplete)} incomplete)" if incomplete else "")
             + (f", {len(copies)} of them {'a copy' if len(copies) == 1 else 'copies'} of another run (counted once)"
                if copies else "")
             + f", {len(recs) - len(read) - len(copies)} unreadable; {curves} curves, {curves - nok} OK, {nok} NOK"
             + (f" ({100 * nok / curves:.2f} %)" if curves else "")
             + (f"; {len(groups)} populations (scene, model level and, where one scene name holds several "
                f"machines, the values that tell them apart), each analysed on its own" if len(groups) > 1 else ""),
             ""]
    for scene in sorted({r.group.split(" (")[0] for r in read if r.variant}):
        variants = sorted({r.variant for r in read if r.variant and r.group.startswith(scene + " (")})
        lines += [f"Note: the recordings of {scene} describe {len(variants)} different machines (their scenes differ "
                  f"beyond seed and run length: {'; '.join(variants)}); pooled, their values would read as one "
                  "machine's scatter, so each is its own population.", ""]
    for (group, seed), runs in sorted(shared_seeds(recs).items()):
        lines += [f"Note: {len(runs)} runs of {group} were made with seed {seed}: the same machines and draws, so "
                  f"their values repeat one another rather than add independent samples (give each run its own seed)."
                  f" ({', '.join(r.path for r in runs[:3])}{', …' if len(runs) > 3 else ''})", ""]
    if len(groups) > 1:
        lines += ["| scene | recordings | curves | OK | NOK |", "|---|---|---|---|---|"]
        for g in groups:
            mine = [r for r in read if r.group == g]
            c, bad = sum(r.curves for r in mine), sum(r.nok for r in mine)
            lines.append(f"| {g} | {len(mine)} | {c} | {c - bad} | {bad} |")
        lines.append("")
    if result.combined:
        kinds = [what for prefix, what in (("stand.", "stand"), ("static.", "static"), ("lab.", "lab"))
                 if any(name.startswith(prefix) for _, name in result.combined)]
        lines += ["## Process values" + (f" and {' and '.join(kinds)} results" if kinds else "")
                  + " per scene (over all its recordings)", "",
                  "| scene | value | unit | n | mean | σ | min | max |", "|---|---|---|---|---|---|---|---|"]
        for (group, name), (m, unit) in sorted(result.combined.items()):
            n, mean, std, lo, hi = _stats(m)
            lines.append(f"| {group} | {name} | {unit} | {n} | {mean:.6g} | {std if std == '' else f'{std:.4g}'} | "
                         f"{lo:.6g} | {hi:.6g} |")
        lines.append("")
    if charts:
        lines += ["## Per recording, against the run's start", "",
                  "Each recording's mean (red: it holds NOK curves) and min … max, the mean and ±3σ of all (black) and "
                  "the program's limits (red); above them the share of NOK curves per recording.", ""]
        for group, png, omitted in charts:
            lines += [f"![{group}]({png})", ""]
            if omitted:
                lines += [f"({group}: {plural(len(omitted), 'more value')} in the table only: {', '.join(omitted)})", ""]
    stands = [r for r in read if r.stand]
    if stands:
        lines += [f"## Stand and lab recordings ({len(stands)})", ""]
        for r in stands[:LISTED]:
            lines += [f"* {r.path}" + (f" (scene {r.scene})" if r.scene else "") + ":"]
            lines += [f"  * {line.strip()}" for line in r.stand]
        lines += [f"* … and {len(stands) - LISTED} more (the table has every one)"] if len(stands) > LISTED else []
        lines.append("")
    for title, chosen, what in (("Recordings with NOK curves", [r for r in read if r.nok], lambda r: f"{r.nok} NOK of {r.curves}"),
                                ("Incomplete recordings (analysed for what they hold)", incomplete,
                                 lambda r: r.incomplete or "incomplete"),
                                ("Copies of another run (same scene, seed and start; counted once)", copies,
                                 lambda r: f"{r.curves} curves; counted: {r.copy_of}"),
                                ("Unreadable recordings", [r for r in recs if r.error], lambda r: r.error)):
        if chosen:
            lines += [f"## {title} ({len(chosen)})", ""]
            lines += [f"* {r.path}: {what(r)}" for r in chosen[:LISTED]]
            lines += [f"* … and {len(chosen) - LISTED} more (the table has every one)"] if len(chosen) > LISTED else []
            lines.append("")
    return lines
