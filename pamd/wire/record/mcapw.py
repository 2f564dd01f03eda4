"""A small chunked MCAP writer made for the io process's hot path and for crashes.

The rare records (header, schemas, channels, metadata, attachments, summary) are
serialised with the `mcap` package's record classes; the hot path is ours: the
recorder packs whole Message records with one precompiled `struct.Struct` and appends
them to the open chunk (`add_record`), with the message index kept as flat arrays.

Crash safety: schemas and channels are written before any chunk; each chunk is
written with `os.write` straight to the file (no user-space buffer) the moment it
closes, followed by its message indexes, so a SIGKILL loses only the open chunk; the
owner calls `sync()` (fsync) on its own period for power cuts. A file whose writer
never reached `finish()` has every complete chunk readable; `files.recover` turns it
into a finalised file.
"""

from __future__ import annotations

import contextlib
import os
import struct
import tempfile
import zlib
from array import array
from collections.abc import Callable, Sequence
from typing import IO

from mcap.data_stream import RecordBuilder
from mcap.opcode import Opcode
from mcap.records import (
    Attachment,
    AttachmentIndex,
    Channel,
    ChunkIndex,
    DataEnd,
    Footer,
    Header,
    McapRecord,
    Message,
    Metadata,
    MetadataIndex,
    Schema,
    Statistics,
    SummaryOffset,
)

MAGIC = b"\x89MCAP0\r\n"
_CHUNK_HEAD = struct.Struct("<BQQQQI")  # opcode, len, start, end, uncompressed size, crc
_U32 = struct.Struct("<I")
_U64 = struct.Struct("<Q")


def _compressor(compression: str) -> Callable[[bytes], bytes] | None:
    if compression == "zstd":
        import zstandard

        compress: Callable[[bytes], bytes] = zstandard.ZstdCompressor(level=3).compress
        return compress
    if compression == "lz4":
        import lz4.frame

        lz4_compress: Callable[[bytes], bytes] = lz4.frame.compress  # lz4 has no types
        return lz4_compress
    if compression in ("", "none"):
        return None
    raise ValueError(f"unknown compression {compression!r}; use zstd, lz4 or none")



def _built(b: RecordBuilder) -> bytes:
    """The records `b` built (mcap's `RecordBuilder.end` carries no type hints)."""
    end: Callable[[], bytes] = b.end
    return end()

class McapWriter:
    """Writes one MCAP file. Not thread-safe; one owner."""

    def __init__(self, path: str, compression: str = "zstd", exclusive: bool = True) -> None:
        flags = os.O_WRONLY | os.O_CREAT | (os.O_EXCL if exclusive else os.O_TRUNC)
        self.path = path
        self.fd = os.open(path, flags, 0o644)
        self.pos = 0
        self.compress = _compressor(compression)
        self.compression = "" if self.compress is None else compression
        self.chunk = bytearray()
        self.index: dict[int, array[int]] = {}  # channel -> flat (log_time, offset) pairs
        self.schemas: list[Schema] = []
        self.channels: list[Channel] = []
        # Chunk indexes, needed only for the summary at the end, go to an unnamed
        # file beside the recording as they are made: a long run (ten chunks a second)
        # would otherwise grow the io process by ~7 KB/s (one ChunkIndex each).
        self.chunk_count = 0
        self._chunk_index_file: IO[bytes] | None = None
        self.attachment_indexes: list[AttachmentIndex] = []
        self.metadata_indexes: list[MetadataIndex] = []
        self.counts: dict[int, int] = {}
        self.message_count = 0
        self.start_ns: int | None = None
        self.end_ns = 0
        self.finished = False
        self.unsynced = 0  # bytes written since the last sync

    # -- low level --------------------------------------------------------------------
    def _write(self, data: bytes | bytearray | memoryview) -> None:
        view = memoryview(data)
        while view:
            n = os.write(self.fd, view)
            view = view[n:]
            self.pos += n
            self.unsynced += n

    def _record(self, rec: McapRecord) -> tuple[int, int]:
        b = RecordBuilder()
        rec.write(b)
        data = _built(b)
        off = self.pos
        self._write(data)
        return off, len(data)

    # -- set-up -----------------------------------------------------------------------
    def start(self, profile: str = "", library: str = "pamd") -> None:
        self._write(MAGIC)
        self._record(Header(profile=profile, library=library))

    def add_schema(self, name: str, encoding: str, data: bytes) -> int:
        s = Schema(id=len(self.schemas) + 1, name=name, encoding=encoding, data=data)
        self.schemas.append(s)
        self._record(s)
        return s.id

    def add_channel(self, topic: str, message_encoding: str, schema_id: int,
                    metadata: dict[str, str] | None = None) -> int:
        c = Channel(id=len(self.channels) + 1, topic=topic, message_encoding=message_encoding,
                    schema_id=schema_id, metadata=dict(metadata or {}))
        self.channels.append(c)
        self.counts[c.id] = 0
        self.index[c.id] = array("Q")
        self._record(c)
        return c.id

    def add_metadata(self, name: str, data: dict[str, str]) -> None:
        self.close_chunk()
        off, n = self._record(Metadata(name=name, metadata=dict(data)))
        self.metadata_indexes.append(MetadataIndex(offset=off, length=n, name=name))

    def add_attachment(self, name: str, media_type: str, data: bytes, log_ns: int,
                       create_ns: int = 0) -> None:
        self.close_chunk()
        att = Attachment(create_time=create_ns, log_time=log_ns, name=name,
                         media_type=media_type, data=data)
        off, n = self._record(att)
        self.attachment_indexes.append(AttachmentIndex(
            offset=off, length=n, log_time=log_ns, create_time=create_ns,
            data_size=len(data), name=name, media_type=media_type))

    # -- messages ---------------------------------------------------------------------
    def add_record(self, channel_id: int, log_ns: int, record: bytes) -> None:
        """Append a whole packed Message record (see `cdr.compile_record`)."""
        chunk = self.chunk
        idx = self.index[channel_id]
        idx.append(log_ns)
        idx.append(len(chunk))
        chunk += record

    def add_message(self, channel_id: int, log_ns: int, data: bytes, sequence: int = 0) -> None:
        b = RecordBuilder()
        Message(channel_id=channel_id, sequence=sequence & 0xFFFFFFFF, log_time=log_ns,
                publish_time=log_ns, data=data).write(b)
        self.add_record(channel_id, log_ns, _built(b))

    def close_chunk(self) -> None:
        """Compress and write the open chunk and its message indexes (if any)."""
        raw = self.chunk
        if not raw:
            return
        start, end = 2**64 - 1, 0
        in_chunk: list[tuple[int, array[int]]] = []
        for ch, idx in self.index.items():
            if idx:
                times = idx[0::2]
                start = min(start, min(times))
                end = max(end, max(times))
                in_chunk.append((ch, idx))
        crc = zlib.crc32(raw)
        data = self.compress(bytes(raw)) if self.compress else bytes(raw)
        comp = self.compression.encode()
        content_len = 8 + 8 + 8 + 4 + 4 + len(comp) + 8 + len(data)
        chunk_off = self.pos
        head = _CHUNK_HEAD.pack(Opcode.CHUNK, content_len, start, end, len(raw), crc)
        self._write(head + _U32.pack(len(comp)) + comp + _U64.pack(len(data)))
        self._write(data)
        chunk_len = self.pos - chunk_off
        # message indexes right after the chunk
        offsets: dict[int, int] = {}
        parts = []
        pos = self.pos
        for ch, idx in in_chunk:
            n = len(idx)
            body = struct.pack(f"<BQHI{n}Q", Opcode.MESSAGE_INDEX, 2 + 4 + 8 * n, ch, 8 * n,
                               *idx)
            offsets[ch] = pos
            pos += len(body)
            parts.append(body)
            self.counts[ch] += n // 2
            self.message_count += n // 2
        idx_bytes = b"".join(parts)
        self._write(idx_bytes)
        self._spill_chunk_index(ChunkIndex(
            message_start_time=start, message_end_time=end, chunk_start_offset=chunk_off,
            chunk_length=chunk_len, message_index_offsets=offsets,
            message_index_length=len(idx_bytes), compression=self.compression,
            compressed_size=len(data), uncompressed_size=len(raw)))
        if self.start_ns is None or start < self.start_ns:
            self.start_ns = start
        self.end_ns = max(self.end_ns, end)
        self.chunk = bytearray()
        for _ch, idx in in_chunk:
            del idx[:]

    def _spill_chunk_index(self, ci: ChunkIndex) -> None:
        if self._chunk_index_file is None:
            self._chunk_index_file = tempfile.TemporaryFile(  # noqa: SIM115 (closed at the end)
                dir=os.path.dirname(os.path.abspath(self.path)), prefix=".pamd-chunk-index-")
        b = RecordBuilder()
        ci.write(b)
        self._chunk_index_file.write(_built(b))
        self.chunk_count += 1

    def _close_spill(self) -> None:
        if self._chunk_index_file is not None:
            with contextlib.suppress(OSError):
                self._chunk_index_file.close()
            self._chunk_index_file = None

    def sync(self) -> None:
        if self.unsynced:
            os.fsync(self.fd)
            self.unsynced = 0

    # -- the end ----------------------------------------------------------------------
    def finish(self) -> None:
        """Close the chunk, write the summary section, footer and magic, fsync, close."""
        if self.finished:
            return
        self.close_chunk()
        self._record(DataEnd(data_section_crc=0))
        summary_start = self.pos
        offsets: list[SummaryOffset] = []
        crc = 0

        def emit(data: bytes) -> None:
            nonlocal crc
            crc = zlib.crc32(data, crc)
            self._write(data)

        def group(opcode: int, records: Sequence[McapRecord]) -> None:
            if not records:
                return
            b = RecordBuilder()
            for r in records:
                r.write(b)
            data = _built(b)
            offsets.append(SummaryOffset(group_opcode=opcode, group_start=self.pos,
                                         group_length=len(data)))
            emit(data)

        stats = Statistics(
            message_count=self.message_count, schema_count=len(self.schemas),
            channel_count=len(self.channels), attachment_count=len(self.attachment_indexes),
            metadata_count=len(self.metadata_indexes), chunk_count=self.chunk_count,
            message_start_time=self.start_ns or 0, message_end_time=self.end_ns,
            channel_message_counts=dict(self.counts))
        group(Opcode.SCHEMA, self.schemas)
        group(Opcode.CHANNEL, self.channels)
        group(Opcode.STATISTICS, [stats])
        spill = self._chunk_index_file
        if spill is not None and self.chunk_count:
            g0 = self.pos
            spill.flush()
            spill.seek(0)
            while block := spill.read(1 << 20):
                emit(block)
            offsets.append(SummaryOffset(group_opcode=Opcode.CHUNK_INDEX, group_start=g0,
                                         group_length=self.pos - g0))
        self._close_spill()
        group(Opcode.ATTACHMENT_INDEX, self.attachment_indexes)
        group(Opcode.METADATA_INDEX, self.metadata_indexes)
        summary_offset_start = self.pos
        b = RecordBuilder()
        for o in offsets:
            o.write(b)
        emit(_built(b))
        crc = zlib.crc32(struct.pack("<BQQQ", Opcode.FOOTER, 20, summary_start,
                                     summary_offset_start), crc)
        fb = RecordBuilder()
        Footer(summary_start=summary_start, summary_offset_start=summary_offset_start,
               summary_crc=crc).write(fb)
        self._write(_built(fb) + MAGIC)
        self.sync()
        os.close(self.fd)
        self.finished = True

    def abandon(self) -> None:
        """Close the descriptor without finishing (after a write error)."""
        if not self.finished:
            self.finished = True
            self._close_spill()
            with contextlib.suppress(OSError):
                os.close(self.fd)
