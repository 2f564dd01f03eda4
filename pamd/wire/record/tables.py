"""A pamd recording's messages as columns: the loop's, each muscle's state, and the
events, decoded once (`read_columns`). The recording API (`pamd.client.recording`) and
training's reader (`pamd.models.data.recordings`) take their columns from these.

Reading is columnar: a state or loop message is a flat CDR struct of fixed size, so a
file's chunks are joined, every message is found by the message indexes written after
each chunk (`indexed_starts`; trusted only if the records they list fill the chunks
back to back, else each record is walked: `record_starts`), and every channel's
payloads are then cut out and decoded at once by numpy through a structured dtype laid
out as the CDR (`payload_dtype`). Decoding message by message (a `struct` call, a list
and its Python floats for each of the ~750 000 messages of the walk-through's sweep)
took seconds of CPU and hundreds of MB; this takes a fraction of that
(bench/waits.py prints both). A file without a chunk index (unfinished: read by
`files.scan`) is read message by message into the same columns.
"""

from __future__ import annotations

import json
import struct
from array import array
from collections.abc import Iterable
from dataclasses import dataclass, field

import numpy as np
from mcap.records import Channel, Message, Schema

from pamd.wire.declare.jsonsafe import JsonObject
from pamd.wire.errors import RecordingError
from pamd.wire.record import cdr, files

#: numpy's type of each struct code a flat CDR message uses (little-endian)
_NUMPY_CODES: dict[str, str] = {
    "?": "?", "B": "u1", "b": "i1", "h": "<i2", "H": "<u2", "i": "<i4", "I": "<u4",
    "q": "<i8", "Q": "<u8", "f": "<f4", "d": "<f8",
}
_RECORD = struct.Struct("<BQ")  # a record's opcode and length
_MESSAGE_HEAD = 2 + 4 + 8 + 8  # channel id, sequence, log time, publish time
_OP_MESSAGE = 5


@dataclass(frozen=True)
class RawEvent:
    """One message of the `/events` topic (JSON), as recorded."""

    t_s: float
    tick: int
    kind: str
    data: JsonObject
    log_ns: int


@dataclass
class Columns:
    """The loop topic's and each muscle's state topic's fields (name -> array, one
    entry per message, in file order, each in its recorded type), and the events. A
    muscle whose topic could not be decoded (not flat CDR) has no columns."""

    loop: dict[str, np.ndarray] = field(default_factory=dict)
    muscles: dict[str, dict[str, np.ndarray]] = field(default_factory=dict)
    events: list[RawEvent] = field(default_factory=list)


def payload_dtype(fields: Iterable[tuple[str, str]]) -> np.dtype[np.void]:
    """The numpy dtype of a flat CDR payload (its 4-byte header, then the fields at
    their CDR alignment, as `cdr.compile_payload` packs them)."""
    names, formats, offsets = [], [], []
    pos = 0
    for name, typ in fields:
        code, size = cdr.PRIMITIVES[typ]
        pos += (-pos) % size
        names.append(name)
        formats.append(_NUMPY_CODES[code])
        offsets.append(4 + pos)
        pos += size
    return np.dtype({"names": names, "formats": formats, "offsets": offsets,
                     "itemsize": 4 + pos})


@dataclass
class _Channel:
    """What a channel is read as: loop, a muscle's state (named) or events; its dtype
    (None: events, JSON) and the parts read so far."""

    role: str  # "loop", "muscle", "events"
    muscle: str = ""
    dtype: np.dtype[np.void] | None = None
    parts: list[np.ndarray] = field(default_factory=list)


class _Reader:
    """The channels of one file, their columns and events as they are read."""

    def __init__(self, path: str, only: str | None) -> None:
        self.path = path
        self.only = only
        self.channels: dict[int, _Channel | None] = {}
        self.events: list[RawEvent] = []

    def channel(self, ch: Channel, schema: Schema | None) -> _Channel | None:
        """How channel `ch` is read (None: not at all), decided at its first message."""
        if ch.id in self.channels:
            return self.channels[ch.id]
        out: _Channel | None = None
        topic = ch.topic
        if "/state/" in topic:
            m = ch.metadata.get("muscle") or topic.rsplit("/", 1)[1]
            if self.only is None or m == self.only:
                out = _Channel("muscle", m, _dtype(ch, schema))
        elif topic.endswith("/loop"):
            out = _Channel("loop", dtype=_dtype(ch, schema))
        elif topic.endswith("/events"):
            out = _Channel("events")
        self.channels[ch.id] = out
        return out

    def chunks(self, chunks: Iterable[files.ChunkData]) -> None:
        """Every message of a file's chunks: the chunks joined into one buffer, each
        message found by the message indexes (else by walking the records), then
        each channel's messages cut out at once."""
        datas: list[bytes] = []
        offsets: list[np.ndarray] = []
        base = 0
        channels: dict[int, Channel] = {}
        schemas: dict[int, Schema] = {}
        indexed = True
        for chunk in chunks:
            channels, schemas = chunk.channels, chunk.schemas
            found = indexed_starts(chunk.message_index) if indexed else None
            indexed = found is not None
            if found is not None:
                offsets.append(found + base)
            datas.append(chunk.data)
            base += len(chunk.data)
        data = b"".join(datas)
        del datas
        buf = np.frombuffer(data, dtype=np.uint8)
        starts = np.sort(np.concatenate(offsets)) if indexed and offsets else None
        if starts is None or not _back_to_back(buf, starts):
            starts = record_starts(data, self.path)  # no index, or one that misses some
        self._messages(data, buf, starts, channels, schemas)

    def _messages(self, data: bytes, buf: np.ndarray, starts: np.ndarray,
                  channels: dict[int, Channel], schemas: dict[int, Schema]
                  ) -> None:
        if not len(starts):
            return
        starts = starts[buf[starts] == _OP_MESSAGE]
        length = _gather(buf, starts + 1, np.dtype("<u8"))
        if len(length) and int(length.min()) < _MESSAGE_HEAD:
            raise RecordingError(f"{self.path}: a message record shorter than its header")
        ids = _gather(buf, starts + 9, np.dtype("<u2"))
        for cid in np.unique(ids):
            ch = channels.get(int(cid))
            if ch is None:
                raise RecordingError(f"{self.path}: a message of unknown channel {int(cid)}")
            reader = self.channel(ch, schemas.get(ch.schema_id))
            if reader is None:
                continue
            sel = ids == cid
            body = starts[sel] + 9 + _MESSAGE_HEAD
            sizes = length[sel].astype(np.int64) - _MESSAGE_HEAD
            if reader.dtype is not None:
                reader.parts.append(self._payloads(buf, body, sizes, reader.dtype, ch.topic))
            elif reader.role == "events":
                log_ns = _gather(buf, starts[sel] + 9 + 6, np.dtype("<u8"))
                for b, n, t in zip(body.tolist(), sizes.tolist(), log_ns.tolist(), strict=True):
                    self.event(data[b:b + n], t)

    def _payloads(self, buf: np.ndarray, body: np.ndarray, sizes: np.ndarray,
                  dtype: np.dtype[np.void], topic: str) -> np.ndarray:
        if len(sizes) and int(sizes.min()) < dtype.itemsize:
            raise RecordingError(f"{self.path}: a message of {topic} holds "
                                 f"{int(sizes.min())} bytes, its schema {dtype.itemsize}")
        rows: np.ndarray = _windows(buf, dtype.itemsize)[body]  # (n, itemsize) bytes
        return rows

    def message(self, ch: Channel, schema: Schema | None, msg: Message
                ) -> None:
        """One message read on its own (a file without a chunk index)."""
        reader = self.channel(ch, schema)
        if reader is None:
            return
        if reader.dtype is not None:
            raw = np.frombuffer(msg.data, dtype=np.uint8)
            if raw.size < reader.dtype.itemsize:
                raise RecordingError(f"{self.path}: a message of {ch.topic} holds "
                                     f"{raw.size} bytes, its schema {reader.dtype.itemsize}")
            reader.parts.append(raw[None, :reader.dtype.itemsize])
        elif reader.role == "events":
            self.event(msg.data, msg.log_time)

    def event(self, data: bytes, log_ns: int) -> None:
        try:
            ev = json.loads(data)
        except ValueError:
            return
        if isinstance(ev, dict):
            self.events.append(RawEvent(float(ev.get("t_s") or 0.0), int(ev.get("tick") or 0),
                                        str(ev.get("kind")), ev.get("data") or {}, log_ns))

    def columns(self) -> Columns:
        out = Columns(events=self.events)
        for reader in self.channels.values():
            if reader is None or reader.role == "events":
                continue
            cols = _fields(reader)
            if reader.role == "loop":
                out.loop = out.loop or cols
            else:
                out.muscles.setdefault(reader.muscle, cols)
        return out


def read_columns(path: str, only: str | None = None) -> Columns:
    """Every message of the recording at `path` (or of muscle `only` and the loop), as
    columns; `RecordingError` if it cannot be read. A muscle is named by its channel's
    `muscle` metadata, else by the last part of its `/state/<muscle>` topic."""
    reader = _Reader(path, only)
    chunks = files.iter_chunk_data(path)
    if chunks is None:
        for ch, schema, msg in files.iter_messages(path):
            reader.message(ch, schema, msg)
    else:
        reader.chunks(chunks)
    return reader.columns()


def _dtype(ch: Channel, schema: Schema | None) -> np.dtype[np.void] | None:
    if ch.message_encoding != "cdr" or schema is None or schema.encoding != "ros2msg":
        return None
    fields = cdr.parse_flat_schema(schema.data.decode("utf-8", "replace"))
    return payload_dtype(fields) if fields else None


def _fields(reader: _Channel) -> dict[str, np.ndarray]:
    """A channel's parts (rows of payload bytes) joined, as one array per field (in
    the schema's order)."""
    if reader.dtype is None:
        return {}
    assert reader.dtype.names is not None
    rows = (np.concatenate(reader.parts) if reader.parts
            else np.zeros((0, reader.dtype.itemsize), dtype=np.uint8))
    table = rows.view(reader.dtype).reshape(-1)
    return {name: np.ascontiguousarray(table[name]) for name in reader.dtype.names}


_INDEX_HEAD = struct.Struct("<BQHI")  # opcode, length, channel id, records' byte length
_OP_MESSAGE_INDEX = 7


def indexed_starts(index: bytes) -> np.ndarray | None:
    """The offsets (in its chunk) of the messages a chunk's message index records
    list, or None if it has none or they cannot be read."""
    if not index:
        return None
    out = []
    pos = 0
    while pos < len(index):
        if len(index) - pos < _INDEX_HEAD.size:
            return None
        opcode, length, _channel, size = _INDEX_HEAD.unpack_from(index, pos)
        if opcode != _OP_MESSAGE_INDEX or size % 16 or size + 6 > length:
            return None
        body = pos + _INDEX_HEAD.size
        if body + size > len(index):
            return None
        out.append(np.frombuffer(index, dtype="<u8", count=size // 8, offset=body)[1::2])
        pos += 9 + length
    return np.concatenate(out).astype(np.int64) if out else np.zeros(0, dtype=np.int64)


def _back_to_back(buf: np.ndarray, starts: np.ndarray) -> bool:
    """Whether records at `starts` (sorted) fill `buf` exactly, one after the other:
    then no record was left out (a message index that lists every message)."""
    if not len(starts):
        return len(buf) == 0
    if starts[0] != 0 or int(starts[-1]) + 9 > len(buf):
        return False
    ends = starts + 9 + _gather(buf, starts + 1, np.dtype("<u8")).astype(np.int64)
    return bool(ends[-1] == len(buf) and np.array_equal(ends[:-1], starts[1:]))


def record_starts(data: bytes, path: str) -> np.ndarray:
    """The offset of every record in the chunks' records, walked one by one."""
    head = _RECORD.unpack_from
    size = len(data)
    out = array("q")
    add = out.append
    pos = 0
    try:
        while pos < size:
            add(pos)
            pos += 9 + head(data, pos)[1]
    except struct.error:
        raise RecordingError(f"{path}: a chunk ends inside a record") from None
    if pos > size:
        raise RecordingError(f"{path}: a chunk ends inside a record")
    return np.frombuffer(out, dtype=np.int64)


def _windows(buf: np.ndarray, width: int) -> np.ndarray:
    """Row i is bytes i .. i + width of `buf` (a view: indexing it copies the rows)."""
    if len(buf) < width:
        return np.zeros((0, width), dtype=np.uint8)
    return np.lib.stride_tricks.sliding_window_view(buf, width)


def _gather(buf: np.ndarray, at: np.ndarray, dtype: np.dtype[np.generic]) -> np.ndarray:
    """The little-endian numbers of `dtype` starting at byte offsets `at` of `buf`."""
    out: np.ndarray = _windows(buf, dtype.itemsize)[at].view(dtype).reshape(-1)
    return out
