"""``rig repair``: a cut or damaged recording (a killed run, a damaged copy) rewritten as a whole MCAP file.

An indexed reader (Foxglove, ``@mcap/core``, the ``mcap`` library's seeking reader) refuses a file without its
summary and footer. The salvage reader (:class:`~rig.recorder.salvage.DataSectionReader`, as ``rig report
--partial``) reads what is whole — every chunk that passes its CRC, up to the cut — and :func:`repair` writes it
again, record for record (schemas, channels, messages with their log, publish times and sequence numbers, the
metadata and attachments), with a summary, an index and a footer. The file says what it is: its end record
``rig.end`` has ``complete = false`` and the reason ``repaired: …`` naming the source and what was lost, so a report
of it says so; the lost parts stay lost.
"""
from __future__ import annotations

import math
import os
from collections import Counter
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from mcap.records import Attachment, Channel, Message, Metadata, Schema
from mcap.writer import CompressionType, Writer

import rig
from rig.recorder import schemas as S
from rig.recorder.reader import Collector, Recording, RecordingError, check_front
from rig.recorder.salvage import DataSectionReader

REPAIR_METADATA = "rig.repair"   # a whole run's file rewritten (nothing of the run lost): what was repaired


@dataclass(frozen=True)
class Repaired:
    """What :func:`repair` wrote: the file, its messages by topic, and what the source lacked (its problems, the lost
    parts first; empty when the source was whole)."""

    path: Path
    messages: dict[str, int]
    problems: list[str]
    whole: bool = False     # every message and the run's end record were read: only the file's index was missing


class _Rewriter:
    """The salvage reader's collector for a repair: every record of a chunk that reads written again, all or none."""

    def __init__(self, source: Path, writer: Writer):
        self.rec = Recording(path=source)
        self.channels: dict[int, str] = {}
        self.orphans: Counter[int] = Counter()
        self.messages: Counter[str] = Counter()
        self._writer = writer
        self._schemas: dict[int, Schema] = {}
        self._defined: dict[int, Channel] = {}
        self._schema_ids: dict[int, int] = {}          # source id -> id in the rewritten file
        self._channel_ids: dict[int, int] = {}
        self.end: dict[str, str] | None = None        # the source's own end record, written last
        self.latest: dict[int, Message] = {}           # per channel its message of the latest log time

    def known(self, summary: Any) -> None:
        """The schemas and channels an intact summary names: a message whose chunk of definitions was lost is kept
        by them (as the salvage reader keeps it)."""
        self._schemas.update(summary.schemas)
        self._defined.update(summary.channels)

    def add(self, record: Any) -> None:
        """Metadata and attachments outside the chunks, copied (the source's end record kept for the end)."""
        if isinstance(record, Metadata):
            self.rec.metadata[record.name] = dict(record.metadata)
            if record.name == S.END_METADATA:
                self.end = dict(record.metadata)
            else:
                self._writer.add_metadata(record.name, dict(record.metadata))
        elif isinstance(record, Attachment):
            self._writer.add_attachment(record.create_time, record.log_time, record.name, record.media_type,
                                        record.data)

    def add_chunk(self, records: list[Any], offset: int | None = None) -> None:
        """A chunk's schemas, channels and messages (a message on a channel defined in a lost part is counted, not
        written)."""
        for record in records:
            if isinstance(record, Schema):
                self._schemas[record.id] = record
            elif isinstance(record, Channel):
                self._defined[record.id] = record
                self.channels[record.id] = record.topic
            elif isinstance(record, Message):
                channel = self._defined.get(record.channel_id)
                if channel is None:
                    self.orphans[record.channel_id] += 1
                    continue
                self._writer.add_message(channel_id=self._channel(channel), log_time=record.log_time,
                                         data=record.data, publish_time=record.publish_time, sequence=record.sequence)
                self.messages[channel.topic] += 1
                if record.channel_id not in self.latest or record.log_time >= self.latest[record.channel_id].log_time:
                    self.latest[record.channel_id] = record

    def simulation_time(self) -> float:
        """Simulation time (s) of the latest data rewritten — a sample, a frame or a message —, as the reader's
        ``last_time``: only each channel's latest message decoded (a block, logged at its first sample, reaches
        further than its log time)."""
        collector = Collector(Recording(path=self.rec.path, metadata=self.rec.metadata), can_frames=False)
        collector.add_chunk([*self._defined.values(), *self.latest.values()])
        return collector.finish().last_time

    def _channel(self, channel: Channel) -> int:
        new = self._channel_ids.get(channel.id)
        if new is None:
            schema_id = 0
            if channel.schema_id:
                schema_id = self._schema_ids.get(channel.schema_id, 0)
                if not schema_id:
                    s = self._schemas[channel.schema_id]
                    schema_id = self._schema_ids[channel.schema_id] = self._writer.register_schema(
                        name=s.name, encoding=s.encoding, data=s.data)
            new = self._channel_ids[channel.id] = self._writer.register_channel(
                topic=channel.topic, message_encoding=channel.message_encoding, schema_id=schema_id,
                metadata=dict(channel.metadata))
        return new


def repair(source: str | Path, out: str | Path) -> Repaired:
    """Rewrite what ``source`` holds as a whole MCAP file ``out`` (written under a hidden part name, renamed when
    whole). A source without a readable message is a :class:`RecordingError`; ``out`` must differ from it."""
    source, out = Path(source), Path(out)
    if out.resolve() == source.resolve():
        raise ValueError(f"{out}: the repaired file must not replace its source (name another with -o)")
    part = out.with_name(f".{out.name}.{os.getpid()}.part")
    try:
        with open(source, "rb") as f, open(part, "wb") as sink:
            size, damage = check_front(source, f)        # empty or not MCAP: an error; a damaged magic: said
            writer = Writer(sink, chunk_size=4 << 20, compression=CompressionType.ZSTD, enable_data_crcs=True)
            writer.start(profile="", library=f"mechrig/{rig.__version__} (rig repair)")
            rewriter = _Rewriter(source, writer)
            reader = DataSectionReader(f, size, rewriter)
            if reader.summary is not None:
                rewriter.known(reader.summary)
            reader.read()
            reader.check()
            reader.finish()
            rec = rewriter.rec
            problems = [str(p) for p in rec.lost] + [p for p in rec.problems if p not in {str(x) for x in rec.lost}]
            problems += [damage] if damage else []      # the magic is rewritten: nothing of the run is lost there
            if not reader.footer and not rec.truncated:
                problems.append("file ends without a footer (recording was not closed)")
            if not rewriter.messages:
                raise RecordingError(f"{source}: no message can be read from it ({'; '.join(problems) or 'empty'}): "
                                     "nothing to repair")
            end = dict(rewriter.end or {})
            kept, counted = sum(rewriter.messages.values()), end.get("messages", "")
            if counted.isdigit() and int(counted) > kept and not rec.lost:    # the end record precedes the last chunk
                problems.append(f"{int(counted) - kept} of the {counted} messages the run's end record counts are "
                                "not in the file (written after that record: the last chunk, lost)")   # in the file
            whole = (end.get("complete") == "true" and counted.isdigit() and int(counted) == kept   # a file cut there
                     and not (rec.lost or rec.damaged or rewriter.orphans))   # read all else: its count tells
            if problems and whole:    # every message and the end record read (e.g. only the summary was cut)
                writer.add_metadata(REPAIR_METADATA, {"source": source.name, "problems": "; ".join(problems)})
            elif problems:            # what was lost, in the file itself: a report of it says so
                was = end.get("reason", "")
                end.update({"complete": "false", "reason": f"{S.REPAIRED} from {source.name}: "
                                                           f"{'; '.join(problems)}" + (f" (it stopped: {was})" if was
                                                                                       else "")})
                end["messages"] = str(sum(rewriter.messages.values()))
                reached = rewriter.simulation_time()
                recorded = end.get("simulation_time")
                if math.isfinite(reached):             # (no message that tells a time: none written)
                    end["simulation_time"] = repr(reached)
                    if recorded not in (None, repr(reached)):  # an end record read, then data of the last chunk lost
                        try:
                            told = f"said {float(recorded):.6g} s of simulation"
                        except ValueError:
                            told = f"gave a damaged simulation time ({recorded!r})"
                        end["reason"] += f" (its end record {told}; the data kept reach {reached:.6g} s)"
            if end:
                writer.add_metadata(S.END_METADATA, end)
            writer.finish()
        os.replace(part, out)
    except BaseException:
        part.unlink(missing_ok=True)
        raise
    return Repaired(out, dict(rewriter.messages), problems, whole)
