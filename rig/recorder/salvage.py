"""Reading an MCAP recording's data section record by record, past damage: a chunk that fails its CRC or does not
decode is skipped and named (:class:`LostPart`, with its time range and messages per topic where the file's indexes
say), bytes that are no record are skipped to where the next record starts (by the summary's index when it is intact,
else at the next whole chunk); a cut file is read up to the cut. :func:`rig.recorder.reader.read_recording` collects
what it reads."""
from __future__ import annotations

import hashlib
import io
import mmap
import struct
import zlib
from bisect import bisect_right
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

from mcap.data_stream import ReadDataStream, RecordBuilder
from mcap.exceptions import EndOfFile, InvalidMagic
from mcap.opcode import Opcode
from mcap.reader import FOOTER_SIZE, make_reader
from mcap.records import Chunk, DataEnd, Footer, MessageIndex
from mcap.stream_reader import CRCValidationError, StreamReader, breakup_chunk
from mcap.summary import Summary

from rig.recorder import schemas as S

if TYPE_CHECKING:
    from rig.recorder.reader import Collector

MCAP_MAGIC = b"\x89MCAP0\r\n"     # every MCAP file's first 8 bytes (and a complete one's last 8)


@dataclass
class LostPart:
    """A part of a damaged recording that was skipped: bytes ``start``-``end``, ``what`` it was (``chunk 2 of 7``,
    ``metadata record 'rig.end'``, ...), ``why`` it could not be read; for a chunk, when known, ``times`` (the
    simulation time range, s, of its messages' log times: from the summary's chunk index, else the chunk's own
    header) and ``messages`` per topic (from its message index)."""

    start: int
    end: int
    what: str
    why: str
    times: tuple[float, float] | None = None
    messages: dict[str, int] | None = None
    held_data: bool = True          # False: an index or framing record (message index, header, data end)
    cut: bool = False               # the chunk the end of a cut file runs into (no damage: the file stops there)
    uncounted: list[str] = field(default_factory=list)     # topics whose message index was not read
    log_times: tuple[int, int] | None = field(default=None, repr=False)     # ns, as recorded
    channel_messages: dict[int, int] | None = field(default=None, repr=False)      # per channel id

    def __str__(self) -> str:
        held = []
        if self.times is not None:
            held.append(f"messages logged at {self.times[0]:.3f}-{self.times[1]:.3f} s of simulation time")
        if self.messages is not None:
            held.append(f"{sum(self.messages.values())} message(s): "
                        + ", ".join(f"{topic} {n}" for topic, n in sorted(self.messages.items())))
        if self.uncounted and self.messages is not None:
            held.append(f"and messages of {', '.join(self.uncounted)}, how many is not known (the message index is "
                        "damaged)")
        elif self.messages is None and self.what.startswith(("chunk", "a chunk")):
            held.append("how many messages is not known (its message index was not read)")
        return (f"{self.what} (bytes {self.start}-{self.end}) {self.why}: {'lost' if self.cut else 'skipped'}"
                + (f"; it held {', '.join(held)}" if held else "")
                + ("" if self.held_data else " (it holds no data of the run: nothing is lost)"))

    def index(self, entries: MessageIndex) -> None:
        """Count the messages of one channel that its message index lists."""
        counts = self.channel_messages if self.channel_messages is not None else {}
        counts[entries.channel_id] = counts.get(entries.channel_id, 0) + len(entries.records)
        self.channel_messages = counts
        if self.log_times is None and entries.records:
            self.log_times = (min(t for t, _ in entries.records), max(t for t, _ in entries.records))

    def name(self, start_ns: int | None, channels: dict[int, str], indexed: set[int] = frozenset()) -> None:
        """Put ``times`` and ``messages`` in the recording's terms: simulation time, topics (``indexed``: the
        channels the summary's chunk index lists for it, each with a message index)."""
        self.uncounted = sorted(channels.get(c, f"channel {c}") for c in indexed - set(self.channel_messages or {}))
        if self.log_times is not None and start_ns is not None:
            self.times = tuple(max(t - start_ns, 0) / 1e9 for t in self.log_times)
        if self.channel_messages is not None:
            self.messages = {}
            for channel, n in self.channel_messages.items():
                topic = channels.get(channel, f"channel {channel}")
                self.messages[topic] = self.messages.get(topic, 0) + n


def _cut(size: int, whole: int, data_end: bool, footer: bool) -> str:
    """Where a cut file ends, in words: what was read before the cut (``whole`` bytes of ``size``)."""
    into = f"{size - whole} bytes into a record" if size > whole else "after a whole record"
    if footer:
        where = "after its footer, without MCAP's closing magic: every record was read"
    elif data_end:
        where = f"in its summary ({into}, after the data end): every message and the end record were read"
    elif whole <= len(MCAP_MAGIC):
        where = f"after MCAP's opening magic{'' if size == whole else f', {into}'}: no record was written"
    else:
        where = f"{into}, without the data end, summary and footer"
    return f"file ends {where} (recording was not closed: the process was killed or the file cut)"


#: what the recorder writes before the summary (channels and schemas are inside chunks)
_DATA_RECORDS = frozenset({Opcode.HEADER, Opcode.METADATA, Opcode.ATTACHMENT, Opcode.CHUNK, Opcode.MESSAGE_INDEX,
                           Opcode.DATA_END})


class _Cut(Exception):
    """The record at an offset reaches past the end of the file."""


def plain(exc: BaseException) -> str:
    """An exception in one line: its type and message (``ZstdError: decompression error: …``)."""
    return f"{type(exc).__name__}: {' '.join(str(exc).split())}" if str(exc) else type(exc).__name__


def _record(f: Any, pos: int, size: int, kinds: frozenset[int] = _DATA_RECORDS) -> tuple[Any, bytes]:
    """The record at byte ``pos`` of ``f`` and its bytes, parsed by the mcap library from exactly the bytes its
    length names. :class:`_Cut` if those reach past the end of the file; an error naming the damage if they are
    not a record of one of ``kinds`` that the library writes back byte for byte (a damaged opcode, length,
    field or check value)."""
    f.seek(pos)
    head = f.read(9)
    if len(head) < 9:
        raise _Cut
    opcode, length = struct.unpack("<BQ", head)        # every MCAP record: opcode, length, fields
    if opcode not in kinds:
        raise ValueError(f"no record the recorder writes starts there (opcode 0x{opcode:02x})")
    if pos + 9 + length > size:
        raise _Cut
    data = head + f.read(length)
    record = next(StreamReader(io.BytesIO(data), skip_magic=True, emit_chunks=True).records)
    again = RecordBuilder()
    record.write(again)
    if again.end() != data:
        raise ValueError(f"its bytes are not those of the {type(record).__name__} record they read as "
                         "(a length or check value is damaged)")
    return record, data


def _summary(f: Any, size: int) -> tuple[tuple[Summary, Footer] | None, str | None]:
    """The file's summary (channels, chunk, metadata and attachment indexes) and footer, when the footer, the
    closing magic and the summary's CRC are intact, else None (a cut file, a damaged footer or summary: offsets not
    to be trusted); and what is damaged when the footer reads but the summary it points to does not (None else: a
    cut file has no footer to check it by)."""
    footer_at = size - len(MCAP_MAGIC) - FOOTER_SIZE
    if footer_at < 2 * len(MCAP_MAGIC):
        return None, None
    try:
        footer, data = _record(f, footer_at, size, frozenset({Opcode.FOOTER}))
        if f.read() != MCAP_MAGIC or not footer.summary_crc or not 0 < footer.summary_start < footer_at:
            return None, None
    except Exception:  # whatever a damaged footer raises: there is no index to use
        return None, None
    damaged = (f"the summary section (bytes {footer.summary_start}-{footer_at}: channels, schemas, indexes, statistics) "
               f"is damaged")
    f.seek(footer.summary_start)
    if zlib.crc32(f.read(footer_at + len(data) - 4 - footer.summary_start)) != footer.summary_crc:
        return None, f"{damaged}: its CRC does not match; other MCAP readers may not open the file"
    try:
        f.seek(size - len(MCAP_MAGIC))     # the reader checks the magic where it starts: the closing one (checked
        summary = make_reader(f).get_summary()   # above), so a damaged opening magic does not hide the summary
    except Exception as exc:  # noqa: BLE001 - whatever the library makes of it
        return None, f"{damaged}: {plain(exc)}"
    return (None, None) if summary is None else ((summary, footer), None)


def _next_chunk(f: Any, start: int, size: int) -> int | None:
    """Offset of the first chunk at or after byte ``start`` that reads whole and passes its CRC (None: there is
    none): where reading resumes after damaged bytes when no intact summary says where the records are."""
    with mmap.mmap(f.fileno(), 0, access=mmap.ACCESS_READ) as view:
        at = view.find(bytes([Opcode.CHUNK]), start)
        while at != -1:
            try:
                chunk, _ = _record(f, at, size, frozenset({Opcode.CHUNK}))
                if chunk.uncompressed_crc:
                    breakup_chunk(chunk, validate_crc=True)
                    return at
            except Exception:  # not a chunk that starts here (or a damaged one): look further
                pass
            at = view.find(bytes([Opcode.CHUNK]), at + 1)
    return None


def chunk_at(f: Any, pos: int) -> Chunk:
    """The chunk whose record starts at byte ``pos`` of ``f``, read from its fields on (past the record's opcode and
    length, which may be the damaged part)."""
    f.seek(pos + 9)
    return Chunk.read(ReadDataStream(f))


class DataSectionReader:
    """Reads a recording's data section in file order into a :class:`Collector`, past damage: a chunk that fails
    its CRC or does not decode is skipped; bytes that are no record are skipped to where the next record starts —
    by the summary's index when the summary is intact (a chunk whose record header is damaged is then read by its
    index entry), else at the next whole chunk. Each skipped part becomes a :class:`LostPart`; a cut file ends
    the reading as before."""

    def __init__(self, f: Any, size: int, collector: "Collector"):
        self.f, self.size, self.collector, self.rec = f, size, collector, collector.rec
        found, summary_damage = _summary(f, size)
        self.summary = None if found is None else found[0]
        self.footer = self.data_end = False
        self.chunks_read = 0
        self.seen: set[int] = set()              # chunk offsets read or lost
        self.contents: dict[bytes, str] = {}     # digest of each chunk read -> its name (a repeated chunk is skipped)
        self.skipped = False                    # bytes were skipped: chunks can no longer be counted from the start
        self.names: dict[int, str] = {}          # offsets the summary indexes: what starts there
        self.index_only: set[int] = set()        # ... of those, records that hold no data of the run
        self.chunks: dict[int, tuple[int, Any]] = {}      # chunk offset -> (number, chunk index)
        if self.summary is not None:
            indexes = sorted(self.summary.chunk_indexes, key=lambda c: c.chunk_start_offset)
            for number, index in enumerate(indexes, 1):
                self.chunks[index.chunk_start_offset] = (number, index)
                self.names[index.chunk_start_offset] = f"chunk {number} of {len(indexes)}"
                self.names.update((offset, f"the message index of chunk {number} of {len(indexes)}")
                                  for offset in index.message_index_offsets.values())
                self.index_only.update(index.message_index_offsets.values())
            self.names.update((m.offset, f"metadata record {m.name!r}") for m in self.summary.metadata_indexes)
            self.names.update((a.offset, f"attachment {a.name!r}") for a in self.summary.attachment_indexes)
            data_end = RecordBuilder()
            DataEnd(0).write(data_end)
            self.names[found[1].summary_start - data_end.count] = "the data end record"
            self.names.setdefault(len(MCAP_MAGIC), "the header")
            self.index_only.update((found[1].summary_start - data_end.count, len(MCAP_MAGIC)))
            self.offsets = sorted(self.names)
            collector.channels.update((i, c.topic) for i, c in self.summary.channels.items())
        self.summary_damaged = summary_damage is not None   # named: the summary's records are not read as a cut
        if summary_damage is not None:
            self._problem(summary_damage)

    def _problem(self, text: str, damage: bool = True) -> None:
        """A problem of the file: damage, or (``damage`` False) a cut."""
        self.rec.truncated = True
        self.rec.damaged = self.rec.damaged or damage
        self.rec.problems.append(text)

    def _chunk_name(self, pos: int) -> str:
        if pos in self.chunks:
            return self.names[pos]
        return f"chunk {self.chunks_read}" if not self.skipped else "a chunk"

    def _lose_chunk(self, pos: int, end: int, chunk: Chunk | None, exc: Exception) -> LostPart:
        why = "fails its CRC (its data was altered)" if isinstance(exc, CRCValidationError) else \
            f"does not decode ({plain(exc)})"
        part = LostPart(pos, end, self._chunk_name(pos), why)
        if pos in self.chunks:
            index = self.chunks[pos][1]
            part.log_times = (index.message_start_time, index.message_end_time)
        elif chunk is not None:
            part.log_times = (chunk.message_start_time, chunk.message_end_time)
        self.rec.lost.append(part)
        return part

    def _lose_cut_chunk(self, pos: int) -> None:
        """Name the chunk a cut file ends in, with the log times its header gives (the recorder writes a chunk
        whole, so what it held is lost; its message index, written after it, is not there to count it)."""
        self.f.seek(pos)
        head = self.f.read(25)                          # opcode, length, message start and end time
        if len(head) == 25 and head[0] == Opcode.CHUNK:
            self.rec.lost.append(LostPart(pos, self.size, self._chunk_name(pos) if self.skipped else
                                          f"chunk {self.chunks_read + 1}", "is cut by the end of the file",
                                          log_times=struct.unpack("<QQ", head[9:25]), cut=True))

    def _chunk(self, pos: int, end: int, chunk: Chunk) -> LostPart | None:
        """Collect a chunk's records; a LostPart if it fails its CRC or does not decode."""
        self.chunks_read += 1
        self.seen.add(pos)
        digest = hashlib.blake2b(chunk.data, digest_size=16,
                                 salt=struct.pack("<QQ", chunk.message_start_time, chunk.message_end_time)).digest()
        if digest in self.contents:          # a broken copy repeated a chunk: its messages would count twice
            self._problem(f"{self._chunk_name(pos)} (bytes {pos}-{end}) repeats {self.contents[digest]} byte for byte "
                          f"(a damaged copy): skipped, its messages counted once")
            return None
        self.contents[digest] = self._chunk_name(pos)
        try:
            self.collector.add_chunk(breakup_chunk(chunk, validate_crc=True), pos)
        except Exception as exc:  # any decoding failure of its data: the chunk is lost, the reading goes on
            return self._lose_chunk(pos, end, chunk, exc)
        return None

    def _resume(self, pos: int, exc: Exception) -> tuple[int | None, LostPart | None]:
        """Skip the damaged record at ``pos``: where reading resumes (None: nowhere, nothing readable follows) and
        the chunk lost there, if it was one (its message index, read next, counts its messages). A chunk whose
        record header is damaged (opcode, length) is read from its header on, as mcap's SeekingReader reads the
        chunk an index entry places, when its data passes its CRC."""
        f = self.f
        if self.summary is not None:
            later = bisect_right(self.offsets, pos)
            resume = self.offsets[later] if later < len(self.offsets) else None
            chunk_here = pos in self.chunks
        else:
            resume = None
            f.seek(pos)
            chunk_here = f.read(1) == bytes([Opcode.CHUNK])
        if chunk_here:
            self.chunks_read += 1
            self.seen.add(pos)
            try:
                chunk = chunk_at(f, pos)
                if not chunk.uncompressed_crc:
                    raise ValueError("it has no CRC to check its data by")
                self.collector.add_chunk(breakup_chunk(chunk, validate_crc=True), pos)
            except Exception as again:  # its data is damaged too: lost
                if self.summary is not None:
                    self.skipped = True
                    return resume, self._lose_chunk(pos, self.size if resume is None else resume, None, again)
            else:
                if self.summary is None:
                    whole = RecordBuilder()
                    chunk.write(whole)
                    resume = pos + whole.count
                self._problem(f"{self._chunk_name(pos)} (byte {pos}): its record header is damaged ({plain(exc)}); "
                              "its data passed its CRC and was read"
                              + (" where the summary's chunk index places it" if self.summary is not None else ""))
                return resume, None
        what = self._chunk_name(pos) if chunk_here else "a damaged record"
        self.skipped = True
        if self.summary is None:
            resume = _next_chunk(f, pos + 1, self.size)
            self.rec.lost.append(LostPart(pos, self.size if resume is None else resume, what,
                                          f"does not read ({plain(exc)})" + (
                                              "; nor do the bytes after it up to the next whole chunk (what they "
                                              "held is not known)" if resume is not None else
                                              "; nor does any chunk after it")))
            return resume, None
        self.rec.lost.append(LostPart(pos, self.size if resume is None else resume,
                                      self.names.get(pos, "an unindexed record"), f"is damaged ({plain(exc)})",
                                      held_data=pos not in self.index_only))
        return resume, None

    def read(self) -> None:
        """Read the data section (then the summary's framing, for the footer)."""
        pos = len(MCAP_MAGIC)
        crc: int | None = zlib.crc32(MCAP_MAGIC)    # of the data section so far (None: bytes were skipped)
        lost: LostPart | None = None                # the chunk lost just before: its message index counts it
        while True:
            failure: Exception | None = None
            try:
                record, data = _record(self.f, pos, self.size)
            except _Cut:
                if self.summary is None and _next_chunk(self.f, pos + 1, self.size) is None:
                    self._lose_cut_chunk(pos)
                    self._problem(_cut(self.size, min(pos, self.size), False, False), damage=False)
                    return
                failure = ValueError("its length reaches past the end of the file")
            except Exception as exc:  # a damaged record: whatever the library raises on its bytes
                failure = exc
            if failure is not None:
                crc = None
                resume, lost = self._resume(pos, failure)
                if resume is None:              # with an intact summary: everything it indexes was read or named
                    self.data_end = self.footer = self.summary is not None
                    return
                pos = resume
                continue
            end = pos + len(data)
            if isinstance(record, DataEnd):
                if crc is not None and record.data_section_crc and record.data_section_crc != crc \
                        and not self.rec.lost:
                    self._problem("the data section's CRC does not match the one written at its end: bytes "
                                  "outside the chunks' checked data (the header, a metadata record, a chunk's header "
                                  "or a message index) were altered after the run — every chunk passed its own CRC "
                                  "and every message was read; the metadata may be damaged")
                self.data_end = True
                self._summary_section(end)
                return
            crc = None if crc is None else zlib.crc32(data, crc)
            if isinstance(record, MessageIndex):
                placed = self.chunks[lost.start][1].message_index_offsets if lost and lost.start in self.chunks \
                    else None              # with an index: count only where it places that channel's message index
                if lost is not None and (placed is None or placed.get(record.channel_id) == pos):
                    lost.index(record)
            elif isinstance(record, Chunk):
                lost = self._chunk(pos, end, record)
            else:
                lost = None
                self.collector.add(record)
            pos = end

    def _summary_section(self, pos: int) -> None:
        """Read the records after the data end (they only repeat the data section's) up to the footer and the
        closing magic: a file cut or damaged there lacks only its index."""
        f, whole = self.f, pos
        f.seek(pos)
        try:
            for record in StreamReader(f, skip_magic=True).records:
                self.footer = self.footer or isinstance(record, Footer)
                whole = f.tell()
        except Exception as exc:  # any failure after the data end: nothing of the run is lost
            if self.summary_damaged:                  # the footer read and pointed at a summary that does not
                self.footer = True
                return
            if self.footer and isinstance(exc, InvalidMagic):
                self._problem("the closing magic after the footer is damaged: every record was read")
            elif isinstance(exc, EndOfFile) or f.tell() >= self.size > whole:
                self._problem(_cut(self.size, whole, True, self.footer), damage=False)
            else:
                self._problem(f"stopped reading at a damaged record of the summary, after the data end "
                              f"({plain(exc)})")

    def check(self) -> None:
        """Name what no other check named: messages on a channel never defined (its channel record was in a lost
        part and no intact summary names it), chunks of the summary's index never reached."""
        orphans = self.collector.orphans
        if orphans:
            self._problem(f"{sum(orphans.values())} message(s) on channel id(s) "
                          f"{', '.join(map(str, sorted(orphans)))} not read: the record defining their channel was in "
                          "a damaged part")
        for pos, (_, index) in self.chunks.items():
            if pos not in self.seen:
                part = LostPart(pos, pos + index.chunk_length, self.names[pos], "was not reached (the bytes before it "
                                "read as records that overlap it)", log_times=(index.message_start_time,
                                                                               index.message_end_time))
                self.rec.lost.append(part)

    def finish(self) -> None:
        """The lost parts in the recording's terms (simulation time, topics), named first among the problems."""
        rec = self.rec
        try:
            start = int(rec.metadata[S.RIG_METADATA]["wall_clock_start"])
        except (KeyError, ValueError):     # no (or a damaged) start: log times cannot be told as simulation times
            start = None
        for part in rec.lost:
            part.name(start, self.collector.channels,
                      set(self.chunks[part.start][1].message_index_offsets) if part.start in self.chunks else set())
        if rec.lost:
            rec.truncated = True
            rec.damaged = rec.damaged or any(not part.cut for part in rec.lost)
            rec.problems[:0] = [str(part) for part in rec.lost]
        rec.read_to_data_end = self.data_end
        rec.data_whole = self.data_end and not any(part.held_data for part in rec.lost) and not self.collector.orphans
