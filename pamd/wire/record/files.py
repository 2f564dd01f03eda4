"""Reading recordings back: check a file, inspect it, export it to CSV, recover an
unfinished one. Every problem with the file is a `RecordingError` with one clear
line (the CLI prints it and exits non-zero), never a traceback.

An unfinished file (SIGKILL, power cut) has no summary or footer; it is read record
by record with the `mcap` package's `StreamReader`, and every chunk that is complete
(its CRC checks) is kept; the truncated tail is reported and dropped.
"""

from __future__ import annotations

import contextlib
import csv
import json
import math
import os
import struct
from collections.abc import Iterator
from dataclasses import dataclass, field
from typing import IO, Protocol

from mcap.data_stream import ReadDataStream
from mcap.exceptions import EndOfFile, McapError
from mcap.opcode import Opcode
from mcap.reader import make_reader
from mcap.records import (
    Attachment,
    Channel,
    Chunk,
    ChunkIndex,
    Footer,
    Header,
    McapRecord,
    Message,
    Metadata,
    Schema,
)
from mcap.stream_reader import StreamReader, breakup_chunk, get_chunk_data_stream

from pamd.wire.declare.jsonsafe import JsonObject, JsonValue
from pamd.wire.errors import RecordingError
from pamd.wire.record import cdr
from pamd.wire.record.mcapw import MAGIC, McapWriter

#: one decoded message's values in its columns' order: numbers (a state or loop message,
#: CDR) or an event's t_s, tick, kind and data (JSON text), as the file holds them
Row = list[JsonValue]


class _RowWriter(Protocol):
    """A CSV writer (`csv.writer`)."""

    def writerow(self, row: list[JsonValue], /) -> object: ...


def check_file(path: str) -> int:
    """Size of `path` if it could be an MCAP file; RecordingError saying why not."""
    if not os.path.exists(path):
        raise RecordingError(f"{path}: no such file")
    if os.path.isdir(path):
        raise RecordingError(f"{path}: is a directory, not an MCAP file")
    size = os.path.getsize(path)
    if size == 0:
        raise RecordingError(f"{path}: empty file (0 bytes), not an MCAP recording")
    with open(path, "rb") as fh:
        head = fh.read(8)
    if head != MAGIC[: len(head)] or len(head) < 8:
        raise RecordingError(f"{path}: not an MCAP file (bad magic bytes)")
    return size


def is_finalised(path: str) -> bool:
    with open(path, "rb") as fh:
        fh.seek(0, os.SEEK_END)
        if fh.tell() < 8 + 9 + 20 + 8:
            return False
        fh.seek(-8, os.SEEK_END)
        return fh.read(8) == MAGIC


@dataclass
class Scan:
    """Everything readable in a file, in file order, chunks validated."""

    header: Header | None = None
    schemas: dict[int, Schema] = field(default_factory=dict)
    channels: dict[int, Channel] = field(default_factory=dict)
    chunks: list[list[McapRecord]] = field(default_factory=list)  # records of each good chunk
    loose: list[Message] = field(default_factory=list)  # messages outside chunks
    metadata: list[Metadata] = field(default_factory=list)
    attachments: list[Attachment] = field(default_factory=list)
    footer: bool = False
    tail_error: str | None = None
    bytes_read: int = 0


def scan(path: str) -> Scan:
    """Read `path` record by record, tolerating a truncated or corrupt tail."""
    size = check_file(path)
    out = Scan()
    with open(path, "rb") as fh:
        reader = StreamReader(fh, emit_chunks=True, record_size_limit=size)
        try:
            for rec in reader.records:
                if isinstance(rec, Chunk):
                    try:
                        inner = breakup_chunk(rec, validate_crc=True)
                    except Exception as exc:  # truncated or corrupt chunk: the tail
                        out.tail_error = f"incomplete chunk ({exc.__class__.__name__})"
                        break
                    for r in inner:
                        if isinstance(r, Schema):
                            out.schemas[r.id] = r
                        elif isinstance(r, Channel):
                            out.channels[r.id] = r
                    out.chunks.append(inner)
                elif isinstance(rec, Header):
                    out.header = rec
                elif isinstance(rec, Schema):
                    out.schemas[rec.id] = rec
                elif isinstance(rec, Channel):
                    out.channels[rec.id] = rec
                elif isinstance(rec, Message):
                    out.loose.append(rec)
                elif isinstance(rec, Metadata):
                    out.metadata.append(rec)
                elif isinstance(rec, Attachment):
                    out.attachments.append(rec)
                elif isinstance(rec, Footer):
                    out.footer = True
                out.bytes_read = fh.tell()
        except (McapError, struct.error, ValueError, EOFError, MemoryError) as exc:
            out.tail_error = f"truncated record ({exc.__class__.__name__}: {exc})"
    if out.header is None:
        raise RecordingError(f"{path}: not a readable MCAP file (no header record)")
    return out


@dataclass(frozen=True)
class ChunkData:
    """One chunk of a finalised file, decompressed: its records back to back (opcode,
    length, body), the message index records written after it (empty if none), and
    the file's channels and schemas to read them by."""

    data: bytes
    message_index: bytes
    channels: dict[int, Channel]
    schemas: dict[int, Schema]


def iter_chunk_data(path: str) -> Iterator[ChunkData] | None:
    """The decompressed chunks of a finalised, chunk-indexed file in the summary's order
    (what `iter_messages` reads, before it cuts them into messages), or None for a file
    without that summary (unfinished, or written without chunk indexes): read it with
    `iter_messages`. A columnar reader finds each chunk's messages itself."""
    if not is_finalised(path):
        return None
    try:
        with open(path, "rb") as fh:
            summary = make_reader(fh).get_summary()
    except (McapError, struct.error, ValueError) as exc:
        raise RecordingError(f"{path}: unreadable MCAP file ({exc})") from None
    if summary is None or not summary.chunk_indexes:
        return None
    return _chunk_data(path, summary.chunk_indexes, dict(summary.channels),
                       dict(summary.schemas))


def _chunk_data(path: str, indexes: list[ChunkIndex], channels: dict[int, Channel],
                schemas: dict[int, Schema]) -> Iterator[ChunkData]:
    try:
        with open(path, "rb") as fh:
            for index in indexes:
                fh.seek(index.chunk_start_offset + 1 + 8)
                stream, size = get_chunk_data_stream(Chunk.read(ReadDataStream(fh)))
                data = stream.read(size)
                message_index = b""
                if index.message_index_offsets and index.message_index_length:
                    fh.seek(index.chunk_start_offset + index.chunk_length)
                    message_index = fh.read(index.message_index_length)
                yield ChunkData(data, message_index, channels, schemas)
    except (McapError, struct.error, ValueError, EOFError) as exc:
        raise RecordingError(f"{path}: unreadable MCAP file ({exc})") from None


def iter_messages(path: str) -> Iterator[tuple[Channel, Schema | None, Message]]:
    """Messages of a finalised or unfinished file, in file order."""
    if is_finalised(path):
        try:
            with open(path, "rb") as fh:
                reader = make_reader(fh)
                summary = reader.get_summary()
                if summary is None or not summary.chunk_indexes:
                    yield from ((c, s, m) for s, c, m in
                                reader.iter_messages(log_time_order=False))
                    return
                # the chunks in the summary's order, as the reader takes them
                for index in summary.chunk_indexes:
                    fh.seek(index.chunk_start_offset + 1 + 8)
                    for m in _chunk_messages(Chunk.read(ReadDataStream(fh))):
                        ch = summary.channels[m.channel_id]
                        yield ch, summary.schemas[ch.schema_id] if ch.schema_id else None, m
            return
        except (McapError, struct.error, ValueError) as exc:
            raise RecordingError(f"{path}: unreadable MCAP file ({exc})") from None
    sc = scan(path)
    for m in sc.loose:
        ch = sc.channels[m.channel_id]
        yield ch, sc.schemas.get(ch.schema_id), m
    for recs in sc.chunks:
        for rec in recs:
            if isinstance(rec, Message):
                ch = sc.channels[rec.channel_id]
                yield ch, sc.schemas.get(ch.schema_id), rec


_RECORD_HEAD = struct.Struct("<BQ")  # opcode, length
_MESSAGE_HEAD = struct.Struct("<HIQQ")  # channel id, sequence, log time, publish time


def _chunk_messages(chunk: Chunk) -> Iterator[Message]:
    """The Message records of a chunk in order, as `mcap`'s `breakup_chunk` reads them
    (its decompression), parsed from the chunk's bytes at once: reading a recording is
    mostly this loop, and `breakup_chunk` reads each field through a stream object."""
    stream, size = get_chunk_data_stream(chunk)
    data = stream.read(size)
    head, fields = _RECORD_HEAD.unpack_from, _MESSAGE_HEAD.unpack_from
    pos = 0
    while pos < size:
        opcode, length = head(data, pos)
        start = pos + 9
        pos = start + length
        if pos > size:
            raise EndOfFile()
        if opcode == Opcode.MESSAGE:
            channel_id, sequence, log_time, publish_time = fields(data, start)
            yield Message(channel_id=channel_id, log_time=log_time, data=data[start + 22:pos],
                          publish_time=publish_time, sequence=sequence)


# -- decoding ------------------------------------------------------------------------
#: a channel's column names, and the struct of its CDR payload (None for JSON)
_ChannelLayout = tuple[list[str], struct.Struct | None]


class Decoder:
    """Per-channel decoding to a flat dict: flat ros2msg CDR by struct, JSON by json."""

    def __init__(self) -> None:
        self._cache: dict[int, _ChannelLayout | None] = {}

    def columns(self, ch: Channel, schema: Schema | None) -> list[str] | None:
        d = self._get(ch, schema)
        return None if d is None else d[0]

    def _get(self, ch: Channel, schema: Schema | None) -> _ChannelLayout | None:
        if ch.id in self._cache:
            return self._cache[ch.id]
        d: _ChannelLayout | None = None
        if ch.message_encoding == "cdr" and schema is not None and schema.encoding == "ros2msg":
            fields = cdr.parse_flat_schema(schema.data.decode("utf-8", "replace"))
            if fields:
                d = ([n for n, _t in fields], cdr.compile_payload(fields))
        elif ch.message_encoding == "json":
            d = (["t_s", "tick", "kind", "data"], None)
        self._cache[ch.id] = d
        return d

    def decode(self, ch: Channel, schema: Schema | None, data: bytes) -> Row | None:
        d = self._get(ch, schema)
        if d is None:
            return None
        names, st = d
        if st is not None:
            return list(st.unpack_from(data))[1:]
        obj = json.loads(data)
        return [obj.get("t_s"), obj.get("tick"), obj.get("kind"),
                json.dumps(obj.get("data"), sort_keys=True)] if isinstance(obj, dict) else None


# -- inspect -------------------------------------------------------------------------
def inspect(path: str) -> JsonObject:
    """`describe` and what only reading every message tells: the faults (events and the
    summary's), the lost records, and that every chunk reads."""
    info, chans, schemas = _describe(path)
    faults, lost_events_seen, last_lost = _events_and_loss(path, chans, schemas)
    summ = info["metadata"].get("pamd.summary", {})
    lost_records = _int(summ.get("lost_records"), last_lost)
    if "faults" in summ:
        with contextlib.suppress(ValueError):
            faults = list(dict.fromkeys(faults + list(json.loads(summ["faults"]))))
    info.update(faults=faults, lost_records=lost_records, lost_record_events=lost_events_seen)
    return info


def describe(path: str) -> JsonObject:
    """A recording's size, status, span, channels (with their message counts), metadata
    and attachments: from a finalised file's summary, without reading its messages (a
    reader that reads them anyway needs no second pass); an unfinished one is scanned."""
    return _describe(path)[0]


@dataclass
class _Contents:
    """What a recording holds, as its summary (or a scan) tells it: channels by topic
    with their message counts, schemas, metadata, attachments, the first and last log
    times, the number of chunks and the file's status."""

    chans: dict[str, Channel] = field(default_factory=dict)
    counts: dict[str, int] = field(default_factory=dict)
    schemas: dict[int, Schema] = field(default_factory=dict)
    metadata: dict[str, dict[str, str]] = field(default_factory=dict)
    attachments: list[JsonObject] = field(default_factory=list)
    start: int | None = None
    end: int | None = None
    chunks: int = 0
    status: str = "finalised"


def _describe(path: str) -> tuple[JsonObject, dict[str, Channel], dict[int, Schema]]:
    size = check_file(path)
    final = is_finalised(path)
    c = _from_summary(path) if final else _from_scan(path)
    start, end = c.start, c.end
    return {
        "file": path, "size_bytes": size, "status": c.status, "finalised": final,
        "chunks": c.chunks, "message_count": sum(c.counts.values()),
        "start_ns": start, "end_ns": end,
        "duration_s": (end - start) / 1e9 if start is not None and end is not None else 0.0,
        "channels": [{"topic": t, "encoding": ch.message_encoding,
                      "schema": c.schemas[ch.schema_id].name if ch.schema_id in c.schemas
                      else "", "messages": c.counts[t]} for t, ch in c.chans.items()],
        "metadata": c.metadata, "attachments": c.attachments,
    }, c.chans, c.schemas


def _from_summary(path: str) -> _Contents:
    """A finalised file's contents, from its summary (its messages unread)."""
    c = _Contents()
    try:
        with open(path, "rb") as fh:
            r = make_reader(fh)
            s = r.get_summary()
            if s is None or s.statistics is None:
                raise RecordingError(f"{path}: finalised but has no summary")
            for ch in s.channels.values():
                c.chans[ch.topic] = ch
                c.counts[ch.topic] = s.statistics.channel_message_counts.get(ch.id, 0)
            c.schemas = dict(s.schemas)
            c.start, c.end = s.statistics.message_start_time, s.statistics.message_end_time
            c.chunks = s.statistics.chunk_count
            for m in r.iter_metadata():
                c.metadata[m.name] = dict(m.metadata)
            for a in r.iter_attachments():
                c.attachments.append({"name": a.name, "media_type": a.media_type,
                                      "bytes": len(a.data)})
    except (McapError, struct.error, ValueError) as exc:
        raise RecordingError(f"{path}: unreadable MCAP file ({exc})") from None
    return c


def _from_scan(path: str) -> _Contents:
    """An unfinished file's contents, scanned record by record."""
    sc = scan(path)
    c = _Contents(status=("unfinished (no summary/footer; run `pamd recover`): " +
                          (sc.tail_error or "ends after a complete record")))
    c.schemas = sc.schemas
    for ch in sc.channels.values():
        c.chans[ch.topic] = ch
        c.counts[ch.topic] = 0
    for m in sc.metadata:
        c.metadata[m.name] = dict(m.metadata)
    c.attachments = [{"name": a.name, "media_type": a.media_type, "bytes": len(a.data)}
                     for a in sc.attachments]
    c.chunks = len(sc.chunks)
    for recs in sc.chunks:
        for rec in recs:
            if isinstance(rec, Message):
                c.counts[sc.channels[rec.channel_id].topic] += 1
                c.start = rec.log_time if c.start is None else min(c.start, rec.log_time)
                c.end = rec.log_time if c.end is None else max(c.end, rec.log_time)
    return c


def _int(v: object, default: int) -> int:
    """A JSON value as an integer, or `default` where it is not one."""
    if not isinstance(v, (int, float, str)):
        return default
    try:
        return int(v)
    except ValueError:
        return default


def _events_and_loss(path: str, chans: dict[str, Channel],
                     schemas: dict[int, Schema]) -> tuple[list[str], int, int]:
    """Faults (transitions into FAULT/ESTOP, recording failures) from the events topic,
    and the lost-record counter of the last loop message."""
    faults: list[str] = []
    lost_events = 0
    last_lost = 0
    ev_ids = {c.id for t, c in chans.items() if t.endswith("/events")}
    loop_ids = {c.id for t, c in chans.items() if t.endswith("/loop")}
    dec = Decoder()
    for ch, schema, m in iter_messages(path):
        if ch.id in ev_ids:
            try:
                ev = json.loads(m.data)
            except ValueError:
                continue
            d = ev.get("data") or {}
            if ev.get("kind") == "transition" and d.get("to") in ("FAULT", "ESTOP"):
                faults.append(str(d.get("reason")))
            elif ev.get("kind") == "recording":
                faults.append(str(d.get("message") or d.get("reason")))
            elif ev.get("kind") == "lost_records":
                lost_events += 1
        elif ch.id in loop_ids:
            cols = dec.columns(ch, schema)
            row = dec.decode(ch, schema, m.data)
            if cols and row and "lost_records" in cols:
                last_lost = int(row[cols.index("lost_records")])
    return faults, lost_events, last_lost


# -- export --------------------------------------------------------------------------
def export_csv(path: str, out_dir: str) -> dict[str, tuple[str, int]]:
    """One CSV per topic (header row: log_time_ns then the message's fields)."""
    check_file(path)
    if not is_finalised(path):
        sc = scan(path)  # raises if nothing is readable
        raise RecordingError(f"{path}: unfinished recording ({sc.tail_error or 'no footer'}); "
                             f"run `pamd recover {path}` first")
    os.makedirs(out_dir, exist_ok=True)
    dec = Decoder()
    writers: dict[int, _RowWriter | None] = {}  # None: a topic not exported
    files: dict[int, IO[str]] = {}
    out: dict[str, tuple[str, int]] = {}
    skipped: set[str] = set()
    try:
        for ch, schema, m in iter_messages(path):
            w = writers.get(ch.id)
            if ch.id not in writers:
                cols = dec.columns(ch, schema)
                if cols is None:
                    skipped.add(ch.topic)
                    writers[ch.id] = None
                    continue
                name = ch.topic.strip("/").replace("/", "_") + ".csv"
                fpath = os.path.join(out_dir, name)
                files[ch.id] = open(fpath, "w", newline="", encoding="utf-8")  # noqa: SIM115
                w = writers[ch.id] = csv.writer(files[ch.id])
                w.writerow(["log_time_ns", *cols])
                out[ch.topic] = (fpath, 0)
            elif w is None:
                continue
            row = dec.decode(ch, schema, m.data)
            if row is None:
                continue
            w.writerow([m.log_time, *("NaN" if isinstance(x, float) and math.isnan(x) else x
                                      for x in row)])
            p, n = out[ch.topic]
            out[ch.topic] = (p, n + 1)
    finally:
        for f in files.values():
            f.close()
    for t in skipped:
        out[t] = ("", -1)
    return out


# -- recover -------------------------------------------------------------------------
RECOVER_MARGIN_BYTES = 1 << 20  # the summary section and slack


def _check_room(out: str, need_bytes: int) -> None:
    """Refuse to start a recovery the output's file system has no room for (the
    recovered file holds at most what was read, plus its summary)."""
    try:
        st = os.statvfs(os.path.dirname(os.path.abspath(out)))
    except OSError:
        return  # the open that follows says why
    free = st.f_bavail * st.f_frsize
    need = need_bytes + RECOVER_MARGIN_BYTES
    if free < need:
        raise RecordingError(f"{out}: its disk has {free} bytes free and the recovered file "
                             f"needs up to {need}; nothing was written. Free some space, or "
                             "recover onto another disk with --out DIR")


def recover(path: str, out: str | None = None, force: bool = False) -> JsonObject:
    """Write a finalised copy of `path` holding every complete chunk."""
    check_file(path)
    if is_finalised(path) and not force:
        return {"file": path, "out": None, "complete": True,
                "message": "already finalised (has a footer); nothing to recover"}
    sc = scan(path)
    stem = path[:-5] if path.endswith(".mcap") else path
    if out is None:
        out = stem + ".recovered.mcap"
    elif os.path.isdir(out):  # a directory (another disk): the default name in it
        out = os.path.join(out, os.path.basename(stem) + ".recovered.mcap")
    if os.path.exists(out):
        raise RecordingError(f"{out}: already exists; choose another with --out")
    _check_room(out, sc.bytes_read)
    try:
        w = McapWriter(out, compression="zstd")
    except OSError as exc:
        raise RecordingError(f"{out}: cannot write ({exc.strerror})") from None
    try:
        w.start(profile=sc.header.profile if sc.header else "", library="pamd recover")
        smap: dict[int, int] = {}
        cmap: dict[int, int] = {}

        def channel(cid: int) -> int:
            if cid not in cmap:
                c = sc.channels[cid]
                sid = 0
                if c.schema_id:
                    if c.schema_id not in smap:
                        s = sc.schemas[c.schema_id]
                        smap[c.schema_id] = w.add_schema(s.name, s.encoding, s.data)
                    sid = smap[c.schema_id]
                cmap[cid] = w.add_channel(c.topic, c.message_encoding, sid, c.metadata)
            return cmap[cid]

        for cid in sorted(sc.channels):
            channel(cid)
        for md in sc.metadata:
            w.add_metadata(md.name, dict(md.metadata))
        for a in sc.attachments:
            w.add_attachment(a.name, a.media_type, a.data, a.log_time, a.create_time)
        n = 0
        last = 0
        for m in sc.loose:
            w.add_message(channel(m.channel_id), m.log_time, m.data, m.sequence)
            n += 1
        w.close_chunk()
        for recs in sc.chunks:
            for rec in recs:
                if isinstance(rec, Message):
                    w.add_message(channel(rec.channel_id), rec.log_time, rec.data, rec.sequence)
                    last = max(last, rec.log_time)
                    n += 1
            w.close_chunk()
        info = {"source": os.path.basename(path), "chunks": str(len(sc.chunks)),
                "messages": str(n), "bytes_read": str(sc.bytes_read),
                "bytes_dropped": str(os.path.getsize(path) - sc.bytes_read),
                "tail": sc.tail_error or "", "last_log_time_ns": str(last)}
        w.add_metadata("pamd.recovered", info)
        w.finish()
    except OSError as exc:
        w.abandon()
        with contextlib.suppress(OSError):
            os.unlink(out)  # never a partial or empty file left behind
        raise RecordingError(f"{out}: write failed ({exc.strerror}); nothing was written. "
                             "Free some space, or recover onto another disk with --out "
                             "DIR") from None
    return {"file": path, "out": out, "complete": False, "chunks": len(sc.chunks),
            "messages": n, "bytes_dropped": os.path.getsize(path) - sc.bytes_read,
            "tail": sc.tail_error, "last_log_time_ns": last}
