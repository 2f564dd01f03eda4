"""A .mat file's structure checked before scipy reads it (`pamd.client.training_tables`), in
bounded memory and time: what it declares is read before what it holds.

A MAT 5 file is a 128-byte header (text, version 0x0100, byte-order mark 'IM' or 'MI')
and tagged elements: a type and a byte count, then the data. A variable is a matrix
element (miMATRIX), whose content is tagged sub-elements (array flags, dimensions,
name, data; a struct's or a cell's members are matrices again), or a compressed
element (miCOMPRESSED: a zlib stream holding one matrix element). scipy reads each
byte count as it comes and allocates it: a 3 MB compressed element that expands to 3
GB is 3 GB of memory, and more in copies, before anything can say no. So first:

- the header: a file shorter than it, a MAT 4 or 7.3 file, or no byte-order mark is
  refused with what it is;
- each element's byte count against the file's end (a truncated file);
- a compressed element's expanded size as its first bytes declare it (the matrix
  tag), before the rest is decompressed; then the stream, decompressed in pieces and
  discarded, must hold what it declares and no more than `limit_bytes` in all;
- each sub-element's byte count against its matrix's, a cell's or a struct's element
  count against its bytes (each is a tagged matrix of at least 8 bytes), the nesting
  depth (`MAX_DEPTH`) and the number of elements (`MAX_ELEMENTS`).
The sum of every variable's expanded size must stay within `limit_bytes`. Every
refusal names the file and the byte offset (in the expanded stream: of the variable's
element). Memory: one piece of the stream at a time (`_PIECE`).
"""

from __future__ import annotations

import os
import struct
import zlib
from typing import BinaryIO, Protocol

from pamd.client.table_checks import shown
from pamd.wire.errors import ModelError

HEADER_BYTES = 128
MI_MATRIX, MI_COMPRESSED = 14, 15
MX_CELL, MX_STRUCT, MX_OBJECT = 1, 2, 3
#: Deepest nesting of structs and cells (scipy reads them recursively).
MAX_DEPTH = 32
#: Most elements (variables, fields, cells) in a file: each is read one by one.
MAX_ELEMENTS = 1_000_000
_PIECE = 1 << 20


class _Stream(Protocol):
    """Bytes read in order: a file's, or a compressed element's expanded."""

    def read(self, n: int) -> bytes: ...

    def skip(self, n: int) -> int: ...


class _FileStream:
    def __init__(self, fh: BinaryIO, end: int) -> None:
        self.fh, self.end = fh, end

    def read(self, n: int) -> bytes:
        return self.fh.read(max(0, min(n, self.end - self.fh.tell())))

    def skip(self, n: int) -> int:
        k = max(0, min(n, self.end - self.fh.tell()))
        self.fh.seek(k, os.SEEK_CUR)
        return k


class _ZlibStream:
    """A compressed element's expansion, `_PIECE` at a time, never held whole."""

    def __init__(self, fh: BinaryIO, compressed_bytes: int, where: str) -> None:
        self.fh, self.left, self.where = fh, compressed_bytes, where
        self.z = zlib.decompressobj()
        self.buf = b""
        self.expanded = 0

    def _more(self, want: int) -> bytes:
        out = []
        got = 0
        while got < want:
            if self.z.unconsumed_tail:
                data = self.z.unconsumed_tail
            elif self.left > 0:
                data = self.fh.read(min(_PIECE, self.left))
                self.left -= len(data)
                if not data:
                    self.left = 0
                    break
            else:
                break
            try:
                piece = self.z.decompress(data, min(_PIECE, want - got))
            except zlib.error as exc:
                raise ModelError(f"{self.where}: its compressed data is corrupt ({exc})"
                                 ) from None
            out.append(piece)
            got += len(piece)
            if self.z.eof:
                break
        self.expanded += got
        return b"".join(out)

    def read(self, n: int) -> bytes:
        if len(self.buf) < n:
            self.buf += self._more(n - len(self.buf))
        data, self.buf = self.buf[:n], self.buf[n:]
        return data

    def skip(self, n: int) -> int:
        k = min(n, len(self.buf))
        self.buf = self.buf[k:]
        while k < n:
            piece = self._more(min(_PIECE, n - k))
            if not piece:
                break
            k += len(piece)
        return k


class _Scan:
    """One file's walk: the expanded bytes and the elements counted so far."""

    def __init__(self, path: str, order: str, limit_bytes: int) -> None:
        self.path, self.order, self.limit = path, order, limit_bytes
        self.total = 0
        self.elements = 0
        self.inside = ""  # where offsets count from: the file, or a compressed variable

    def refuse(self, offset: int, what: str) -> ModelError:
        return ModelError(f"{shown(self.path)}: {self.inside}byte {offset}: {what}; not a MAT "
                          "file pamd can read (save it again from MATLAB with save(..., "
                          "'-v7'), or export CSV)")

    def tag(self, s: _Stream, offset: int, room: int) -> tuple[int, int, int]:
        """(type, byte count, bytes the tag and its data take) of the element at
        `offset`, which must fit in `room` bytes."""
        if room < 8:
            raise self.refuse(offset, f"an element's tag in the last {room} bytes of its "
                              "matrix (corrupt)")
        raw = s.read(8)
        if len(raw) < 8:
            raise self.refuse(offset, f"an element's tag is cut off ({len(raw)} of 8 "
                              "bytes): the file is truncated")
        mdtype, nbytes = struct.unpack(self.order + "II", raw)
        if mdtype >> 16:  # the small data element: 2-byte count, 4 bytes of data
            return mdtype & 0xFFFF, mdtype >> 16, 8
        taken = 8 + nbytes + (-nbytes % 8 if mdtype != MI_COMPRESSED else 0)
        if 8 + nbytes > room:
            raise self.refuse(offset, f"an element declares {nbytes} bytes where {room - 8} "
                              "are left (truncated or corrupt)")
        self.elements += 1
        if self.elements > MAX_ELEMENTS:
            raise self.refuse(offset, f"more than {MAX_ELEMENTS} elements (variables, "
                              "fields, cells)")
        return mdtype, nbytes, min(taken, room)

    def matrix(self, s: _Stream, offset: int, size: int, depth: int) -> None:
        """Walk a matrix's content of `size` bytes: its sub-elements' counts, and for a
        cell or a struct its member count (from its array flags and dimensions)."""
        if depth > MAX_DEPTH:
            raise self.refuse(offset, f"structs or cells nested deeper than {MAX_DEPTH}")
        done = index = 0
        has_members = False
        while done < size:
            at = offset + done
            mdtype, nbytes, taken = self.tag(s, at, size - done)
            body = taken - 8
            if mdtype == MI_MATRIX:
                self.matrix(s, at + 8, nbytes, depth + 1)
                s.skip(body - nbytes)
            elif index < 2:  # the array flags, then the dimensions
                data = s.read(body)[:nbytes]
                if index == 0 and len(data) >= 4:
                    klass = struct.unpack(self.order + "I", data[:4])[0] & 0xFF
                    has_members = klass in (MX_CELL, MX_STRUCT, MX_OBJECT)
                elif has_members:
                    self.members(data, at, size)
            elif s.skip(body) < body:
                raise self.refuse(at, "the data ends inside an element (truncated)")
            done += taken
            index += 1

    def members(self, dims: bytes, offset: int, size: int) -> None:
        """A cell's or a struct's member count must fit its bytes: each member is a
        matrix of at least an 8-byte tag."""
        count = 1
        for k in range(len(dims) // 4):
            d = struct.unpack(self.order + "i", dims[4 * k:4 * k + 4])[0]
            if d < 0:
                raise self.refuse(offset, f"a negative dimension ({d})")
            count *= d
        if count * 8 > size:
            raise self.refuse(offset, f"a cell or struct of {count} members in {size} bytes "
                              "(each needs at least 8)")

    def add(self, offset: int, expanded: int) -> None:
        self.total += expanded
        if self.total > self.limit:
            raise ModelError(
                f"{shown(self.path)}: byte {offset}: its variables hold more than "
                f"{self.limit >> 20} MiB expanded ({self.total >> 20} MiB so far): more than "
                "a training table may (pamd.client.table_checks.MAX_TABLE_BYTES); record long "
                "runs as MCAP (pamd run --record) or split the table")


def check_mat(path: str, limit_bytes: int) -> None:
    """Refuse (ModelError) a .mat file scipy should not be given (module doc)."""
    size = os.path.getsize(path)
    with open(path, "rb") as fh:
        head = fh.read(HEADER_BYTES)
        if len(head) < HEADER_BYTES:
            raise ModelError(f"{shown(path)}: {len(head)} bytes, shorter than a MAT file's "
                             f"{HEADER_BYTES}-byte header: not a MAT file")
        order = {b"IM": "<", b"MI": ">"}.get(head[126:128])
        if head.startswith(b"MATLAB 7.3") or (order and struct.unpack(
                order + "H", head[124:126])[0] == 0x0200):
            raise ModelError(f"{shown(path)}: a MAT 7.3 (HDF5) file; save it with "
                             "save(..., '-v7') or export CSV")
        if order is None or struct.unpack(order + "H", head[124:126])[0] != 0x0100:
            raise ModelError(f"{shown(path)}: not a MAT 5 file (bytes 124-127 hold no MAT 5 "
                             "version and byte-order mark 'IM'/'MI': a MAT 4 file, or not a "
                             "MAT file); save it with save(..., '-v7') or export CSV")
        scan = _Scan(path, order, limit_bytes)
        top = _FileStream(fh, size)
        offset = HEADER_BYTES
        while offset < size:
            mdtype, nbytes, taken = scan.tag(top, offset, size - offset)
            if mdtype == MI_COMPRESSED:
                _compressed(scan, fh, offset, nbytes)
            elif mdtype == MI_MATRIX:
                scan.add(offset, nbytes)
                scan.matrix(top, offset + 8, nbytes, 1)
            offset += taken
            fh.seek(offset)


def _compressed(scan: _Scan, fh: BinaryIO, offset: int, nbytes: int) -> None:
    """One compressed element: its declared expansion first, then the stream walked."""
    where = f"{shown(scan.path)}: byte {offset}"
    z = _ZlibStream(fh, nbytes, where)
    scan.inside = f"the variable compressed at byte {offset}, expanded "
    mdtype, inner, _ = scan.tag(z, 0, 1 << 62)  # its size judged by `add`, next
    scan.add(offset, 8 + inner)  # refused here, before the rest is decompressed
    if mdtype == MI_MATRIX:
        scan.matrix(z, 8, inner, 1)
    elif z.skip(inner) < inner:
        raise scan.refuse(0, "its compressed data ends before what it declares")
    if z.expanded < 8 + inner:
        raise scan.refuse(0, f"its compressed data expands to {z.expanded} bytes where it "
                          f"declares {8 + inner}")
    scan.inside = ""
