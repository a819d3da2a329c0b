"""MCAP at the recorder's pace: a chunked writer and a chunk reader for this package's bags.

The ``mcap`` library builds every message through a record object and a ``BytesIO`` and reads
every record through a byte stream; for the ~3 messages a step of a 20 kHz drive that costs more
than simulating it. Here the hot paths are our own and everything rare is the library's:

- :class:`ChunkWriter` appends each message to the open chunk with one ``struct`` pack, or a
  block of records at once (:class:`MessageGroup`: the state, reference and command of hundreds
  of steps, and the tool messages among them, built in one numpy array), and keeps the message
  index and statistics as plain lists and counters; headers, schemas, channels, metadata, chunk
  and index records and the summary are the library's record classes. With the same calls it
  writes a file byte for byte equal to ``mcap.writer.Writer``'s (chunked, zstd at the library's
  level, every index, statistics, summary offsets, CRCs on; ``test_mcapio.py`` holds it to
  that, blocks included).
- :func:`read_file` walks a file's top-level records, decompresses each chunk whole into a
  numpy array and notes where each message lies — from the message index that follows the chunk, gathering the
  message heads with numpy (record by record where there is no index) — so a caller can decode
  a channel of fixed-size messages in one numpy gather (:meth:`Messages.payloads`). A file cut
  short is read up to its last whole chunk, as the library's stream reader reads it.
"""

from __future__ import annotations

import io
import struct
import sys
import zlib
from collections.abc import Iterator, Sequence
from concurrent.futures import Future, ThreadPoolExecutor
from dataclasses import dataclass, field
from typing import IO, Any

import numpy as np
import zstandard
from mcap.data_stream import ReadDataStream, RecordBuilder
from mcap.opcode import Opcode
from mcap.records import (
    Channel,
    ChunkIndex,
    DataEnd,
    Footer,
    Header,
    Metadata,
    MetadataIndex,
    Schema,
    Statistics,
    SummaryOffset,
)

__all__ = ["MAGIC", "ChunkWriter", "McapContents", "MessageGroup", "Messages", "read_file"]

#: the first (and last) bytes of every MCAP file
MAGIC = b"\x89MCAP0\r\n"
#: a message record's head: opcode, record length, channel, sequence, log time, publish time
_MESSAGE = struct.Struct("<BQHIQQ")
_MESSAGE_HEAD = _MESSAGE.size  # 31
_RECORD = struct.Struct("<BQ")
_CHUNK_HEAD = struct.Struct("<QQQI")  # start, end, uncompressed size, uncompressed crc
#: a chunk record up to its compression string: opcode, length, the head, the string's length
_CHUNK_RECORD = struct.Struct("<BQQQQII")
#: a message index record's head: opcode, record length, channel, the entries' byte length
_INDEX_HEAD = struct.Struct("<BQHI")


class ChunkWriter:
    """Write an MCAP file to ``out`` (anything with ``write`` and ``tell``): messages go into
    chunks of about ``chunk_size`` uncompressed bytes, each zstd-compressed and written whole
    when full. Call :meth:`start`, register schemas and channels, add messages and metadata,
    then :meth:`finish`. An ``OSError`` of ``out`` reaches the caller as it happens."""

    def __init__(
        self,
        out: IO[bytes] | Any,
        *,
        chunk_size: int,
        level: int = 3,
        background: bool = False,
    ) -> None:
        """``level``: zstd's compression level (3: what ``zstandard.compress()`` and so the
        ``mcap`` library's writer use); ``background``: a thread of its own compresses and
        writes each full chunk while the caller goes on filling the next (zstd and the file
        release the GIL); one chunk is in flight at most. Call :meth:`close` when done
        (``finish`` does not)."""
        self._out = out
        self._pool = ThreadPoolExecutor(1, "mcap-chunks") if background else None
        if background:
            _quick_switch(+1)
        self._pending: tuple[Future[tuple[bytes, int]], Any] | None = None
        self._chunk_size = chunk_size
        self._zstd = zstandard.ZstdCompressor(level=level)
        self._chunk = bytearray()
        #: channel → (log times, offsets) of its messages in the open chunk
        self._index: dict[int, tuple[list[int], list[int]]] = {}
        self._schemas: list[Schema] = []
        self._channels: list[Channel] = []
        #: messages by channel id (index 0 unused): the last sequence number :meth:`add` gave
        self.counts = [0]
        self._first_seen: dict[int, None] = {}  #: channels in order of their first message
        self._chunk_indexes: list[ChunkIndex] = []  #: of the chunks written
        self._bounds: list[tuple[int, int]] = []  #: (first, last) log time of each sealed chunk
        self._metadata_indexes: list[MetadataIndex] = []

    def start(self, *, profile: str, library: str) -> None:
        self._out.write(MAGIC)
        self._records(Header(profile, library))

    def register_schema(self, name: str, encoding: str, data: bytes) -> int:
        schema = Schema(id=len(self._schemas) + 1, name=name, encoding=encoding, data=data)
        self._schemas.append(schema)
        self._chunk += _record_bytes(schema)
        self._maybe_finalize()
        return schema.id

    def register_channel(
        self, topic: str, message_encoding: str, schema_id: int, metadata: dict[str, str]
    ) -> int:
        channel = Channel(
            id=len(self._channels) + 1,
            topic=topic,
            message_encoding=message_encoding,
            schema_id=schema_id,
            metadata=metadata,
        )
        self._channels.append(channel)
        self.counts.append(0)
        self._chunk += _record_bytes(channel)
        self._maybe_finalize()
        return channel.id

    def add(self, channel_id: int, time_ns: int, data: bytes) -> None:
        """A message logged and published at ``time_ns``, with the channel's next sequence
        number (1, 2, 3, ..., as rosbag2 numbers them per topic)."""
        self.add_message(channel_id, time_ns, data, time_ns, self.counts[channel_id] + 1)

    def add_message(
        self, channel_id: int, log_time: int, data: bytes, publish_time: int, sequence: int
    ) -> None:
        """Any message (``mcap.writer.Writer.add_message``'s arguments)."""
        self.counts[channel_id] += 1
        chunk = self._chunk
        index = self._index.get(channel_id)
        if index is None:
            index = self._index[channel_id] = ([], [])
        index[0].append(log_time)
        index[1].append(len(chunk))
        chunk += _MESSAGE.pack(5, 22 + len(data), channel_id, sequence, log_time, publish_time)
        chunk += data
        if len(chunk) > self._chunk_size:
            self._finalize()

    def add_block(
        self, block: bytes | memoryview, by_channel: dict[int, tuple[np.ndarray, np.ndarray]]
    ) -> None:
        """Message records one after another (each channel's next sequence numbers already in
        them): ``by_channel`` gives each channel's log times and where its records begin in
        ``block``, in order (every record of the block is one of them). The same as
        :meth:`add_message` of each in turn: a chunk ends after the record that takes it past
        its size."""
        for ch, (ts, _) in by_channel.items():
            self.counts[ch] += len(ts)
        size = len(block)
        if len(self._chunk) + size <= self._chunk_size:  # no record ends past the size
            self._index_block(by_channel, 0, size, len(self._chunk))
            self._chunk += block
            return
        begins = np.sort(np.concatenate([offsets for _, offsets in by_channel.values()]))
        ends = np.append(begins[1:], size)
        done = 0  #: bytes of the block in chunks already
        while done < size:
            base = len(self._chunk) - done  #: a block offset's place in the open chunk
            # the record after which the chunk is full: the first to end past its size
            full = int(np.searchsorted(ends, self._chunk_size - base, side="right"))
            cut = int(ends[full]) if full < len(ends) else size
            self._index_block(by_channel, done, cut, base)
            self._chunk += block[done:cut]
            done = cut
            if full < len(ends):
                self._finalize()

    def _index_block(
        self, by_channel: dict[int, tuple[np.ndarray, np.ndarray]], start: int, end: int, base: int
    ) -> None:
        """The index entries of a block's records that begin in [start, end), at ``base`` +
        their offset in the open chunk; channels new to the chunk in the order of their first
        record."""
        part = []
        for ch, (ts, offsets) in by_channel.items():
            i, j = np.searchsorted(offsets, (start, end)).tolist()
            if j > i:
                part.append((int(offsets[i]), ch, ts[i:j], offsets[i:j]))
        if len(part) > 1:
            part.sort()
        index = self._index
        for _, ch, ts, offsets in part:
            entry = index.get(ch)
            if entry is None:
                entry = index[ch] = ([], [])
            entry[0].extend(ts.tolist())
            entry[1].extend((offsets + base).tolist())

    def group(self, parts: Sequence[tuple[int, bytes, int]], extras_after: int = 0) -> MessageGroup:
        """A :class:`MessageGroup` of (channel id, payload prefix, bytes after it) parts."""
        return MessageGroup(self, parts, extras_after)

    @property
    def message_count(self) -> int:
        return sum(self.counts)

    @property
    def first_time(self) -> int | None:
        """The earliest log time written (None before the first message)."""
        times = [start for start, _ in self._bounds]
        times += (min(ts) for ts, _ in self._index.values())
        return min(times, default=None)

    @property
    def last_time(self) -> int:
        """The latest log time written (0 before the first message)."""
        times = [end for _, end in self._bounds]
        times += (max(ts) for ts, _ in self._index.values())
        return max(times, default=0)

    def add_metadata(self, name: str, data: dict[str, str]) -> None:
        self.drain()  # after the chunks before it, as the library writes it
        offset = self._out.tell()
        record = _record_bytes(Metadata(name=name, metadata=data))
        self._metadata_indexes.append(MetadataIndex(offset=offset, length=len(record), name=name))
        self._out.write(record)

    def finish(self) -> None:
        """The chunk in progress, then the summary (schemas, channels, statistics, chunk and
        metadata indexes, summary offsets) and the footer."""
        self._finalize()
        self.drain()
        self._records(DataEnd(0))
        start = self._out.tell()
        summary = RecordBuilder()
        offsets = []
        chunks = self._chunk_indexes
        statistics = Statistics(
            attachment_count=0,
            channel_count=len(self._channels),
            channel_message_counts={ch: self.counts[ch] for ch in self._first_seen},
            chunk_count=len(chunks),
            message_count=sum(self.counts),
            message_end_time=max((c.message_end_time for c in chunks), default=0),
            message_start_time=min((c.message_start_time for c in chunks), default=0),
            metadata_count=len(self._metadata_indexes),
            schema_count=len(self._schemas),
        )
        groups: list[tuple[Opcode, list[Any]]] = [
            (Opcode.SCHEMA, list(self._schemas)),
            (Opcode.CHANNEL, list(self._channels)),
            (Opcode.STATISTICS, [statistics]),
            (Opcode.CHUNK_INDEX, self._chunk_indexes),
            (Opcode.ATTACHMENT_INDEX, []),
            (Opcode.METADATA_INDEX, self._metadata_indexes),
        ]
        for opcode, records in groups:
            group_start = summary.count
            for r in records:
                r.write(summary)
            offsets.append(SummaryOffset(opcode, start + group_start, summary.count - group_start))
        offset_start = start + summary.count
        for o in offsets:
            o.write(summary)
        data = summary.end()
        crc = zlib.crc32(data)
        crc = zlib.crc32(struct.pack("<BQQQ", Opcode.FOOTER, 20, start, offset_start), crc)
        self._out.write(data)
        self._records(
            Footer(summary_start=start, summary_offset_start=offset_start, summary_crc=crc)
        )
        self._out.write(MAGIC)

    def _maybe_finalize(self) -> None:
        if len(self._chunk) > self._chunk_size:
            self._finalize()

    def _finalize(self) -> None:
        """Seal the open chunk (if it holds a message): compressed here, or by the compressing
        thread while the next chunk fills; a sealed chunk is written when it is compressed and
        the one after it is sealed (or at :meth:`drain`), so one chunk waits at most."""
        if not self._index:
            return
        first = min(min(ts) for ts, _ in self._index.values())
        last = max(max(ts) for ts, _ in self._index.values())
        for channel_id in self._index:
            self._first_seen.setdefault(channel_id, None)
        raw = bytes(self._chunk)
        sealed = (raw, self._index, first, last)
        self._bounds.append(sealed[2:])
        self._chunk = bytearray()
        self._index = {}
        if self._pool is None:
            self._write_chunk(_compress(self._zstd, raw), *sealed)
            return
        self.drain()
        self._pending = (self._pool.submit(_compress, self._zstd, raw), sealed)

    def drain(self) -> None:
        """Write the sealed chunk still waiting (once it is compressed); an OSError of the file
        is raised here."""
        pending, self._pending = self._pending, None
        if pending is not None:
            future, sealed = pending
            self._write_chunk(future.result(), *sealed)

    def close(self) -> None:
        """End the compressing thread (after :meth:`finish`, or when giving up on the file)."""
        if self._pool is not None:
            self._pool.shutdown(wait=True)
            self._pool = None
            _quick_switch(-1)

    def _write_chunk(
        self,
        packed: tuple[bytes, int],
        raw: bytes,
        index: dict[int, tuple[list[int], list[int]]],
        start: int,
        end: int,
    ) -> None:
        compressed, crc = packed
        compression = b"zstd"
        head = _CHUNK_RECORD.pack(
            Opcode.CHUNK,
            _CHUNK_HEAD.size + 4 + len(compression) + 8 + len(compressed),
            start,
            end,
            len(raw),
            crc,
            len(compression),
        )
        chunk_offset = self._out.tell()
        record_length = len(head) + len(compression) + 8 + len(compressed)
        # each channel's message index record (mcap.records.MessageIndex): (time, offset) pairs
        parts: list[bytes] = []
        offsets = {}
        at = chunk_offset + record_length
        for channel_id, (ts, where) in index.items():
            n = len(ts)
            entries = np.empty(2 * n, dtype="<u8")
            entries[0::2] = ts
            entries[1::2] = where
            part = _INDEX_HEAD.pack(Opcode.MESSAGE_INDEX, 6 + 16 * n, channel_id, 16 * n)
            offsets[channel_id] = at
            at += len(part) + 16 * n
            parts += (part, entries.tobytes())
        index_bytes = b"".join(parts)
        # one write: the chunk record and its message indexes
        self._out.write(
            b"".join(
                (head, compression, struct.pack("<Q", len(compressed)), compressed, index_bytes)
            )
        )
        self._chunk_indexes.append(
            ChunkIndex(
                message_start_time=start,
                message_end_time=end,
                chunk_start_offset=chunk_offset,
                chunk_length=record_length,
                message_index_offsets=offsets,
                message_index_length=len(index_bytes),
                compression="zstd",
                compressed_size=len(compressed),
                uncompressed_size=len(raw),
            )
        )

    def _records(self, *records: Any) -> None:
        self._out.write(b"".join(_record_bytes(r) for r in records))


class MessageGroup:
    """The messages of consecutive steps, each step three or four on channels of their own (a
    step's state, reference and command, and the plant's losses) with a payload of a constant
    prefix (may be empty) then a fixed number of bytes, and now and then other messages after
    one of a step's records (the plant's tool messages). :meth:`add_steps` builds the records of
    many steps in one numpy array and hands them to the writer as one block: the bytes are those
    :meth:`ChunkWriter.add` of each message in turn writes, chunk boundaries included."""

    def __init__(
        self, writer: ChunkWriter, parts: Sequence[tuple[int, bytes, int]], extras_after: int = 0
    ) -> None:
        if len(parts) not in (3, 4):
            raise ValueError(f"a message group has three or four parts, not {len(parts)}")
        self._w = writer
        self._after = extras_after  #: the part of a step the extra messages follow
        self._channels = [ch for ch, _, _ in parts]
        self._sizes = [n for _, _, n in parts]  #: each payload's bytes after its prefix
        fields: list[tuple[str, Any]] = []
        for i, (_, prefix, n) in enumerate(parts):
            fields += [(f"op{i}", "u1"), (f"len{i}", "<u8"), (f"ch{i}", "<u2")]
            fields += [(f"seq{i}", "<u4"), (f"log{i}", "<u8"), (f"pub{i}", "<u8")]
            if prefix:
                fields.append((f"pre{i}", f"V{len(prefix)}"))
            fields.append((f"body{i}", f"V{n}"))
        self._dtype = np.dtype(fields)  # packed: no padding between fields
        self._row = self._dtype.itemsize
        #: where each record begins in a step's row, and where the row ends
        self._at = np.cumsum([0] + [_MESSAGE_HEAD + len(p) + n for _, p, n in parts])
        template = np.zeros(1, self._dtype)
        for i, (ch, prefix, n) in enumerate(parts):
            template[f"op{i}"] = 5
            template[f"len{i}"] = 22 + len(prefix) + n
            template[f"ch{i}"] = ch
            if prefix:
                template[f"pre{i}"] = np.frombuffer(prefix, dtype=f"V{len(prefix)}")
        self._template = template
        self._rows = np.repeat(template, 0)  #: the array filled last time (reused when it fits)

    def add_steps(
        self,
        times: Sequence[np.ndarray],
        payloads: Sequence[bytes | bytearray | memoryview],
        extras: Sequence[tuple[int, Sequence[tuple[int, int, bytes]]]] = (),
    ) -> None:
        """``n`` steps: ``times[j]`` the log (and publish) times of part ``j``'s messages (int64
        ns), ``payloads[j]`` their bytes after the prefix, one after another. ``extras``: (step,
        [(channel, time, payload), ...]) in step order, messages written right after that step's
        part ``extras_after`` (on channels other than the group's)."""
        n = len(times[0])
        if n == 0:
            return
        w = self._w
        if len(self._rows) < n:
            self._rows = np.repeat(self._template, n)
        rows = self._rows[:n]
        counts = w.counts
        for j, ch in enumerate(self._channels):
            rows[f"seq{j}"] = np.arange(counts[ch] + 1, counts[ch] + 1 + n, dtype=np.uint32)
            rows[f"log{j}"] = times[j]
            rows[f"pub{j}"] = times[j]
            rows[f"body{j}"] = np.frombuffer(payloads[j], dtype=f"V{self._sizes[j]}")
        raw = rows.view(np.uint8).data
        starts = np.arange(n, dtype=np.int64) * self._row
        if not extras:
            w.add_block(
                raw, {ch: (times[j], starts + self._at[j]) for j, ch in enumerate(self._channels)}
            )
            return
        # the extra messages go in after their steps' part extras_after: the rows are cut there
        grown = np.zeros(n, dtype=np.int64)  #: the extra bytes inside each step's row
        after = self._after
        cut_at = int(self._at[after + 1])
        pieces: list[Any] = []
        extra: dict[int, tuple[list[int], list[int]]] = {}  #: channel → times, offsets
        at = shift = 0
        for step, messages in extras:
            cut = step * self._row + cut_at
            pieces.append(raw[at:cut])
            at = cut
            pos = cut + shift
            for ch, t, data in messages:
                sequence = w.counts[ch] + len(extra.get(ch, ((), ()))[0]) + 1
                record = _MESSAGE.pack(5, 22 + len(data), ch, sequence, t, t) + data
                pieces.append(record)
                ts, offsets = extra.setdefault(ch, ([], []))
                ts.append(t)
                offsets.append(pos)
                pos += len(record)
            grown[step] = pos - cut - shift
            shift = pos - cut
        pieces.append(raw[at:])
        before = np.cumsum(grown) - grown  #: extra bytes before each step's row
        by_channel = {
            ch: (times[j], starts + self._at[j] + (before if j <= after else before + grown))
            for j, ch in enumerate(self._channels)
        }
        for ch, (ts, offsets) in extra.items():
            by_channel[ch] = (np.asarray(ts, dtype=np.int64), np.asarray(offsets, dtype=np.int64))
        w.add_block(b"".join(pieces), by_channel)


#: writers with a compressing thread, and the switch interval before the first of them
_SWITCH: list[Any] = [0, None]
#: s: how long the compressing thread may wait for the GIL at most while they write
QUICK_SWITCH = 0.001


def _quick_switch(change: int) -> None:
    """While a writer with a compressing thread is open, Python hands the GIL over within
    QUICK_SWITCH rather than its default 5 ms: the thread needs it briefly before and after each
    chunk it compresses, and a simulation in pure Python never lets go of it on its own (at
    5 ms the chunk would come back later than the next one fills)."""
    if change > 0 and _SWITCH[0] == 0:
        _SWITCH[1] = sys.getswitchinterval()
        sys.setswitchinterval(min(QUICK_SWITCH, _SWITCH[1]))
    _SWITCH[0] += change
    if change < 0 and _SWITCH[0] == 0:
        sys.setswitchinterval(_SWITCH[1])


def _compress(zstd: Any, raw: bytes) -> tuple[bytes, int]:
    """A chunk's compressed bytes and its CRC (neither holds the GIL while it works)."""
    return zstd.compress(raw), zlib.crc32(raw)


def _record_bytes(record: Any) -> bytes:
    b = RecordBuilder()
    record.write(b)
    out: bytes = b.end()
    return out


# --- reading --------------------------------------------------------------------------------

#: a message record's head as numpy reads it (see _MESSAGE)
_HEAD = np.dtype(
    [("op", "u1"), ("len", "<u8"), ("ch", "<u2"), ("seq", "<u4"), ("log", "<u8"), ("pub", "<u8")]
)
#: where a message lies and what its head says, one row per message (see :class:`Messages`)
_WHERE = np.dtype(
    [("start", "<i8"), ("length", "<i8"), ("log", "<u8"), ("pub", "<u8"), ("seq", "<u4"),
     ("order", "<i8")]
)  # fmt: skip


class Messages:
    """The messages of one channel, in file order: where each one's payload lies in
    :attr:`McapContents.data`, its length, log and publish time and sequence number, and its
    place in the whole file's message order — each an array, one entry a message."""

    def __init__(self, channel: Channel) -> None:
        self.channel = channel
        self._parts: list[np.ndarray] = []  #: while reading: a _WHERE array per chunk
        self._seal()

    def _add(self, rows: np.ndarray) -> None:
        self._parts.append(rows)

    def _seal(self) -> None:
        """The file is read: the chunks' rows, one array per field."""
        rows = np.concatenate([np.empty(0, _WHERE), *self._parts])
        self._parts = []
        self.starts: np.ndarray = rows["start"]
        self.lengths: np.ndarray = rows["length"]
        self.log_times: np.ndarray = rows["log"]
        self.publish_times: np.ndarray = rows["pub"]
        self.sequences: np.ndarray = rows["seq"]
        self.order: np.ndarray = rows["order"]

    def __len__(self) -> int:
        return len(self.starts)

    def payloads(self, data: np.ndarray, length: int) -> np.ndarray:
        """Every payload as a row of an (n, ``length``) uint8 array, in one numpy gather
        (every message of the channel must be ``length`` bytes long)."""
        windows = np.lib.stride_tricks.sliding_window_view(data, length)  # no copy
        rows: np.ndarray = windows[self.starts]
        return rows


@dataclass
class McapContents:
    """A file read by :func:`read_file`: its channels' messages (payloads in :attr:`data`, the
    chunks' uncompressed bytes one after another), the metadata records by name, and whether the
    file ended as a closed file does (data end, summary, footer, magic)."""

    data: np.ndarray  #: uint8
    channels: dict[int, Messages]
    metadata: dict[str, dict[str, str]]
    complete: bool
    messages: int = 0
    #: while reading: the chunks' bytes (joined into :attr:`data` at the end), and their size
    parts: list[np.ndarray] = field(default_factory=list)
    size: int = 0

    def payload(self, m: Messages, i: int) -> bytes:
        s = int(m.starts[i])
        return self.data[s : s + int(m.lengths[i])].tobytes()

    def in_file_order(self) -> Iterator[tuple[Channel, int, int, int, bytes]]:
        """(channel, log time, publish time, sequence, payload) of every message, file order."""
        where = [(n, m, i) for m in self.channels.values() for i, n in enumerate(m.order.tolist())]
        where.sort(key=lambda w: w[0])
        for _, m, i in where:
            log, pub, seq = int(m.log_times[i]), int(m.publish_times[i]), int(m.sequences[i])
            yield m.channel, log, pub, seq, self.payload(m, i)


def read_file(path: Any) -> McapContents:
    """Every message of an MCAP file as :class:`McapContents`. The top-level records are read
    in order; a chunk is decompressed whole. Reading stops quietly at a record cut short or
    unreadable (a writer killed mid-write): what came before is the contents, ``complete``
    False. Raises ``OSError`` if the file cannot be read, ``ValueError`` if it is not MCAP."""
    with open(path, "rb") as f:
        raw = f.read()
    if raw[: len(MAGIC)] != MAGIC:
        raise ValueError(f"{path}: not an MCAP file")
    records = _top_level(raw)
    out = McapContents(np.empty(0, dtype=np.uint8), {}, {}, False)
    unzstd = zstandard.ZstdDecompressor()
    for i, (op, body, length) in enumerate(records):
        if op == Opcode.CHUNK:
            try:
                _chunk(out, raw, body, unzstd, _message_index(raw, records, i + 1))
            except (zstandard.ZstdError, ValueError, struct.error, MemoryError):
                break  # a chunk cut or damaged (its size too): what came before stands
        elif op == Opcode.METADATA:
            md = Metadata.read(ReadDataStream(_view(raw, body, length)))
            out.metadata[md.name] = dict(md.metadata)
        elif op == Opcode.CHANNEL:
            _add_channel(out, Channel.read(ReadDataStream(_view(raw, body, length))))
        elif op == Opcode.MESSAGE:  # an unchunked file
            record = np.frombuffer(raw, np.uint8, 9 + length, body - 9)
            at = np.zeros(1, dtype=np.int64)
            try:
                _place(out, record, at, _heads(record, at))
            except ValueError:
                break
        elif op == Opcode.FOOTER:
            out.complete = raw[body + length : body + length + len(MAGIC)] == MAGIC
            break
    if out.parts:
        out.data, out.parts = np.concatenate(out.parts), []
    for m in out.channels.values():
        m._seal()
    return out


def _top_level(raw: bytes) -> list[tuple[int, int, int]]:
    """(opcode, where its body begins, its length) of each whole top-level record, in order,
    up to the first one cut short."""
    records = []
    pos, end = len(MAGIC), len(raw)
    unpack = _RECORD.unpack_from
    while pos + 9 <= end:
        op, length = unpack(raw, pos)
        body = pos + 9
        if body + length > end:
            break  # cut short
        records.append((op, body, length))
        if op == Opcode.FOOTER:
            break
        pos = body + length
    return records


def _view(raw: bytes | np.ndarray, start: int, length: int) -> Any:
    part = raw[start : start + length]
    return io.BytesIO(part if isinstance(part, bytes) else part.tobytes())


def _add_channel(out: McapContents, channel: Channel) -> None:
    if channel.id not in out.channels:
        out.channels[channel.id] = Messages(channel)


def _message_index(
    raw: bytes, records: list[tuple[int, int, int]], first: int
) -> np.ndarray | None:
    """Where a chunk's messages begin in it, from the message index records that follow the
    chunk (``records[first:]``, sorted); None when there are none, or one does not add up."""
    found = []
    for op, body, length in records[first:]:
        if op != Opcode.MESSAGE_INDEX:
            break
        if length < 6:
            return None
        (size,) = struct.unpack_from("<I", raw, body + 2)
        if size % 16 or 6 + size > length:
            return None
        pairs = np.frombuffer(raw, dtype="<u8", count=size // 8, offset=body + 6)
        found.append(pairs[1::2])
    if not found:
        return None
    return np.sort(np.concatenate(found)).astype(np.int64)


def _chunk(
    out: McapContents, raw: bytes, body: int, unzstd: Any, index: np.ndarray | None = None
) -> None:
    """A chunk's records: its bytes decompressed into their place in ``out.data``, its channels
    and messages noted (from ``index``, its message index, where that covers the chunk)."""
    _start, _end, size, crc = _CHUNK_HEAD.unpack_from(raw, body)
    pos = body + _CHUNK_HEAD.size
    (n,) = struct.unpack_from("<I", raw, pos)
    compression = raw[pos + 4 : pos + 4 + n].decode()
    pos += 4 + n
    (clen,) = struct.unpack_from("<Q", raw, pos)
    pos += 8
    blob = memoryview(raw)[pos : pos + clen]
    data = np.empty(size, dtype=np.uint8)
    if compression == "zstd":
        if _decompress_into(unzstd, blob, data) != size:
            raise ValueError("chunk damaged")
    elif compression == "" and len(blob) == size:
        data[:] = np.frombuffer(blob, dtype=np.uint8)
    elif compression == "":
        raise ValueError("chunk damaged")
    else:
        raise ValueError(f"compression {compression!r} is not read here")
    if crc and zlib.crc32(data.data) != crc:
        raise ValueError("chunk damaged")
    heads = None if index is None else _indexed_heads(out, data, index)
    if index is None or heads is None:
        index = _record_positions(out, data)
        heads = _heads(data, index)
    _place(out, data, index, heads)


def _decompress_into(unzstd: Any, blob: memoryview, into: np.ndarray) -> int:
    """Decompress one zstd frame into ``into``; how many bytes it holds (-1: more than fit)."""
    reader = unzstd.stream_reader(blob)
    view = into.data
    got = 0
    while got < len(into):
        n = reader.readinto(view[got:])
        if not n:
            return got
        got += n
    return -1 if reader.read(1) else got


def _heads(data: np.ndarray, at: np.ndarray) -> np.ndarray:
    """The heads of the message records beginning at ``at`` in ``data`` (a _HEAD array)."""
    rows = np.lib.stride_tricks.sliding_window_view(data, _MESSAGE_HEAD)[at]
    heads: np.ndarray = rows.view(_HEAD).ravel()
    return heads


def _indexed_heads(out: McapContents, data: np.ndarray, at: np.ndarray) -> np.ndarray | None:
    """The heads of a chunk's messages where its message index says they begin (``at``), once
    checked against the chunk's bytes; the records between them (channels, schemas) are read
    one by one and their channels added. None when the index does not cover every message of
    the chunk."""
    size = len(data)
    if not len(at) or at[0] < 0 or at[-1] + _MESSAGE_HEAD > size:
        return None
    heads = _heads(data, at)
    ends = at + 9 + heads["len"].astype(np.int64)
    if (
        (heads["op"] != Opcode.MESSAGE).any()
        or (heads["len"] < _MESSAGE_HEAD - 9).any()
        or (ends[:-1] > at[1:]).any()
        or ends[-1] > size
    ):
        return None
    # what lies between the messages: other records (channels, schemas), never a message
    channels = []
    starts, stops = np.append(0, ends), np.append(at, size)
    gaps = np.flatnonzero(stops > starts)
    for start, stop in zip(starts[gaps].tolist(), stops[gaps].tolist()):
        pos = start
        while pos + 9 <= stop:
            op, length = _RECORD.unpack_from(data.data, pos)
            if op == Opcode.MESSAGE:
                return None  # a message the index does not have
            if op == Opcode.CHANNEL:
                channels.append(_channel(data, pos, length))
            pos += 9 + length
    for channel in channels:
        _add_channel(out, channel)
    return heads


def _record_positions(out: McapContents, data: np.ndarray) -> np.ndarray:
    """Where the messages of a chunk's (or an unchunked file's) records begin, read record by
    record (a chunk with no message index); its channels are added as they come."""
    at = []
    pos, end = 0, len(data)
    unpack = _RECORD.unpack_from
    view = data.data
    while pos + 9 <= end:
        op, length = unpack(view, pos)
        if pos + 9 + length > end:
            raise ValueError("a record runs past the end of its chunk")
        if op == Opcode.MESSAGE:
            if length < _MESSAGE_HEAD - 9:
                raise ValueError("a message record shorter than a message's head")
            at.append(pos)
        elif op == Opcode.CHANNEL:
            _add_channel(out, _channel(data, pos, length))
        pos += 9 + length
    return np.array(at, dtype=np.int64)


def _channel(data: np.ndarray, pos: int, length: int) -> Channel:
    """The channel record at ``pos`` of a chunk's bytes."""
    channel: Channel = Channel.read(ReadDataStream(_view(data, pos + 9, length)))
    return channel


def _place(out: McapContents, data: np.ndarray, at: np.ndarray, heads: np.ndarray) -> None:
    """A chunk's bytes (or an unchunked message's record) appended to ``out``: its messages
    begin at ``at`` in them, with these ``heads``; noted by channel."""
    if len(at):
        ids = heads["ch"]
        found = np.unique(ids).tolist()
        if not set(found) <= set(out.channels):
            raise ValueError("a message of a channel the file never declared")
        rows = np.empty(len(at), _WHERE)
        rows["start"] = at + out.size + _MESSAGE_HEAD
        rows["length"] = heads["len"].astype(np.int64) - 22
        rows["log"] = heads["log"]
        rows["pub"] = heads["pub"]
        rows["seq"] = heads["seq"]
        rows["order"] = np.arange(out.messages, out.messages + len(at))
        for ch in found:
            out.channels[ch]._add(rows[ids == ch] if len(found) > 1 else rows)
        out.messages += len(at)
    out.parts.append(data)
    out.size += len(data)
