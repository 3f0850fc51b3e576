"""The building blocks of a report (headings, text, tables, figures, links) and what a section sees
(:class:`ReportContext`). A *section* is a function ``(ctx: ReportContext) -> list[Block]``; the report
(:mod:`rig.analysis.report`) lists the sections and renders their blocks to HTML or Markdown."""
from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Callable

from rig.analysis.units import DisplayUnits, recording_units
from rig.recorder import Recording

NOK_PLOTS = 12        # NOK curves plotted by default (the report says how many of how many)


@dataclass
class Heading:
    text: str
    level: int = 2


@dataclass
class Text:
    text: str
    kind: str = ""        # "", "warning" or "note": how the HTML shows it


@dataclass
class Banner:
    """The verdict in one line, green (``ok``) or red."""
    text: str
    ok: bool


@dataclass(frozen=True)
class Link:
    """A table cell linking to a file of the report (``href`` relative to the report)."""
    text: str
    href: str


@dataclass
class Table:
    headers: list[str]
    rows: list[list[Any]]
    collapsed: str | None = None     # HTML: folded away under this summary line (long tables)


@dataclass
class Figure:
    path: str          # relative to the report directory
    caption: str


Block = Heading | Text | Banner | Table | Figure


@dataclass
class ReportContext:
    """What sections see: the recording, its analysis, the output directory, how many OK and NOK curves get
    their own figure, a figure counter, the files sections exported for the exports table (path, contents) and the
    notes already given in full (``said``)."""

    recording: Recording
    analysis: dict
    out_dir: Path
    ok_plots: int = 0
    nok_plots: int = NOK_PLOTS
    _count: list[int] = field(default_factory=lambda: [0])
    exported: list[tuple[Path, str]] = field(default_factory=list)
    said: set[str] = field(default_factory=set)     # notes a section gave in full: a later one refers back to it

    def figure_path(self, stem: str) -> Path:
        self._count[0] += 1
        return self.out_dir / f"{self._count[0]:03d}_{stem}.png"

    def figure(self, path: Path, caption: str) -> Figure:
        return Figure(path.relative_to(self.out_dir).as_posix(), caption)

    def units(self, program: int) -> DisplayUnits:
        """Display units of a program (from the analysis, else from the recording)."""
        known = self.analysis.get("units") or {}
        return known[program] if program in known else recording_units(self.recording, program)

    @property
    def main_program(self) -> int:
        """The recording's program: its first curve's, else its first program's (a stand), else 0."""
        rec = self.recording
        return rec.curves[0].program if rec.curves else next(iter(rec.programs), 0)

    @property
    def main_units(self) -> DisplayUnits:
        """Display units of :attr:`main_program`."""
        return self.units(self.main_program)

    @property
    def nok(self) -> set[int]:
        return {v["number"] for v in self.analysis["verdicts"] if not v["ok"]}


Section = Callable[[ReportContext], list[Block]]


def fmt(v: Any) -> str:
    """Table cell text: numbers to 4 significant digits, None as a dash."""
    if v is None:
        return "—"
    if isinstance(v, bool):
        return "yes" if v else "no"
    if isinstance(v, float):
        return "—" if v != v else f"{v:.4g}"
    return str(v)

