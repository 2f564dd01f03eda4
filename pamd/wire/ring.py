"""The shared-memory block and its lock-free single-producer single-consumer rings.

One `multiprocessing.shared_memory` block holds a control header (io state,
heartbeat, stop flag, error text, file list) and three rings:

- ticks:    loop -> io, fixed-size tick records (bytes of the record's array('d'));
- events:   loop -> io, JSON in fixed slots (transitions, commands, verdicts, markers);
- commands: io -> loop, JSON in fixed slots (parsed remote commands).

Each ring has a `head` (written only by its producer) and a `tail` (written only by
its consumer) as monotonically increasing 64-bit counters on their own cache lines.
The producer writes a slot, then publishes it by storing `head + 1`; the consumer
reads slots below `head`, then frees them by storing the new `tail`. Aligned 8-byte
stores are single machine stores, so no lock is needed or held. Nothing here blocks:
`put` on a full ring returns False and the caller decides (count, or wait).
"""

from __future__ import annotations

import contextlib
import struct
from dataclasses import dataclass
from multiprocessing import shared_memory
from typing import Protocol

MAGIC = 0x31444D4150  # "PAMD1"
CTRL_BYTES = 4096
RING_HDR_BYTES = 128  # head on one cache line, tail on the next

# control header, u64 indices
C_MAGIC, C_HEARTBEAT, C_IO_STATE, C_STOP, C_T_START_SET, C_T_START, C_RECORDED = range(7)
C_LOST_EVENTS = 7
C_LOOP_LOST = 8  # tick records the loop lost to a full ring so far (written as it loses one)
ERR_OFF, ERR_MAX = 1024, 1020
FILES_OFF, FILES_MAX = 2048, 2044

IO_STARTING, IO_READY, IO_FAILED, IO_DONE = 0, 1, 2, 3

_U32 = struct.Struct("<I")
_F64 = struct.Struct("<d")


@dataclass(frozen=True)
class BlockLayout:
    """Sizes of the three rings; both processes derive the same offsets from it."""

    record_bytes: int
    tick_slots: int
    event_slots: int = 256
    event_slot_bytes: int = 8192
    command_slots: int = 32
    command_slot_bytes: int = 4096

    def __post_init__(self) -> None:
        for n in (self.tick_slots, self.event_slots, self.command_slots):
            if n <= 0 or n & (n - 1):
                raise ValueError("ring slot counts must be powers of two")

    @property
    def tick_off(self) -> int:
        return CTRL_BYTES

    @property
    def event_off(self) -> int:
        return self.tick_off + RING_HDR_BYTES + self.tick_slots * self.record_bytes

    @property
    def command_off(self) -> int:
        return self.event_off + RING_HDR_BYTES + self.event_slots * self.event_slot_bytes

    @property
    def total_bytes(self) -> int:
        return self.command_off + RING_HDR_BYTES + self.command_slots * self.command_slot_bytes


def pow2_at_least(n: int) -> int:
    p = 1
    while p < n:
        p <<= 1
    return p


class Ring:
    """One SPSC ring inside the block. Use from one producer and one consumer only."""

    def __init__(self, buf: memoryview, u64: memoryview, off: int, slots: int,
                 slot_bytes: int) -> None:
        self.buf = buf
        self.u64 = u64
        self.i_head = off // 8
        self.i_tail = (off + 64) // 8
        self.slots = slots
        self.mask = slots - 1
        self.slot_bytes = slot_bytes
        self.base = off + RING_HDR_BYTES
        # private copies of our own counter (the other side's is always re-read)
        self.head = u64[self.i_head]
        self.tail = u64[self.i_tail]

    # -- producer ------------------------------------------------------------------
    def free(self) -> int:
        return self.slots - (self.head - self.u64[self.i_tail])

    def put(self, data: memoryview | bytes) -> bool:
        """Copy `data` (exactly `slot_bytes` long) into the next slot; False if full."""
        head = self.head
        if head - self.u64[self.i_tail] >= self.slots:
            return False
        off = self.base + (head & self.mask) * self.slot_bytes
        self.buf[off:off + self.slot_bytes] = data
        self.head = head = head + 1
        self.u64[self.i_head] = head
        return True

    def put_blob(self, blob: bytes) -> bool:
        """Length-prefixed `blob` (at most slot_bytes - 4) into the next slot."""
        head = self.head
        if head - self.u64[self.i_tail] >= self.slots:
            return False
        n = len(blob)
        if n > self.slot_bytes - 4:
            raise ValueError(f"blob of {n} bytes exceeds the slot ({self.slot_bytes - 4})")
        off = self.base + (head & self.mask) * self.slot_bytes
        _U32.pack_into(self.buf, off, n)
        self.buf[off + 4:off + 4 + n] = blob
        self.head = head = head + 1
        self.u64[self.i_head] = head
        return True

    # -- consumer ------------------------------------------------------------------
    def available(self) -> int:
        return self.u64[self.i_head] - self.tail

    def slot_offset(self, seq: int) -> int:
        return self.base + (seq & self.mask) * self.slot_bytes

    def release(self, upto: int) -> None:
        """Free every slot below sequence number `upto`."""
        self.tail = upto
        self.u64[self.i_tail] = upto

    def get_blob(self) -> bytes | None:
        if self.u64[self.i_head] == self.tail:
            return None
        off = self.slot_offset(self.tail)
        (n,) = _U32.unpack_from(self.buf, off)
        blob = bytes(self.buf[off + 4:off + 4 + n])
        self.release(self.tail + 1)
        return blob


class SharedBlock:
    """The control header and the three rings over one shared-memory block."""

    def __init__(self, layout: BlockLayout, name: str | None = None,
                 create: bool = False) -> None:
        self.layout = layout
        if create:
            self.shm = shared_memory.SharedMemory(create=True, size=layout.total_bytes)
        else:
            self.shm = shared_memory.SharedMemory(name=name)
        self.owner = create
        self.buf, self.u64 = mapped_views(self.shm)
        if create:
            # touch every page now, so the loop never page-faults on a fresh slot
            self.buf[:layout.total_bytes] = bytes(layout.total_bytes)
            for off in (layout.tick_off, layout.event_off, layout.command_off):
                self.buf[off:off + RING_HDR_BYTES] = bytes(RING_HDR_BYTES)
            self.u64[C_MAGIC] = MAGIC
        elif self.u64[C_MAGIC] != MAGIC:
            raise RuntimeError(f"shared block {name!r} is not a pamd block")
        lo = layout
        self.ticks = Ring(self.buf, self.u64, lo.tick_off, lo.tick_slots, lo.record_bytes)
        self.events = Ring(self.buf, self.u64, lo.event_off, lo.event_slots,
                           lo.event_slot_bytes)
        self.commands = Ring(self.buf, self.u64, lo.command_off, lo.command_slots,
                             lo.command_slot_bytes)

    @property
    def name(self) -> str:
        return self.shm.name

    # -- control header --------------------------------------------------------------
    def get(self, index: int) -> int:
        return self.u64[index]

    def set(self, index: int, value: int) -> None:
        self.u64[index] = value

    def set_t_start(self, t_s: float) -> None:
        _F64.pack_into(self.buf, C_T_START * 8, t_s)
        self.u64[C_T_START_SET] = 1

    def t_start(self) -> float | None:
        if not self.u64[C_T_START_SET]:
            return None
        t_s: float = _F64.unpack_from(self.buf, C_T_START * 8)[0]
        return t_s

    def newest_f64(self, i: int) -> float | None:
        """The `i`-th float of the newest tick record the loop put into its ring, read
        or not (None before the first): the io process sees how far the loop is without
        draining. The loop writes the next slot, never this one."""
        head = self.u64[self.ticks.i_head]
        if head == 0:
            return None
        value: float = _F64.unpack_from(self.buf, self.ticks.slot_offset(head - 1) + 8 * i)[0]
        return value

    def loop_lost(self) -> int:
        """Tick records the loop lost to a full ring so far (C_LOOP_LOST)."""
        return self.u64[C_LOOP_LOST]

    def _set_text(self, off: int, cap: int, text: str) -> None:
        data = text.encode("utf-8", "replace")[:cap]
        self.buf[off + 4:off + 4 + len(data)] = data
        _U32.pack_into(self.buf, off, len(data))  # length last: readers see whole text

    def _get_text(self, off: int) -> str:
        (n,) = _U32.unpack_from(self.buf, off)
        return bytes(self.buf[off + 4:off + 4 + n]).decode("utf-8", "replace")

    def set_error(self, text: str) -> None:
        self._set_text(ERR_OFF, ERR_MAX, text)

    def error(self) -> str:
        return self._get_text(ERR_OFF)

    def set_files(self, files: list[str]) -> None:
        """The recording's files, as many of the newest as fit (whole names): a
        daemon that rotates its files for months shows the ones it writes now."""
        kept: list[str] = []
        size = -1
        for f in reversed(files):
            size += len(f.encode("utf-8", "replace")) + 1
            if size > FILES_MAX:
                break
            kept.append(f)
        self._set_text(FILES_OFF, FILES_MAX, "\n".join(reversed(kept)))

    def files(self) -> list[str]:
        text = self._get_text(FILES_OFF)
        return text.split("\n") if text else []

    def close(self) -> None:
        """Release our mapping (and remove the block if we created it)."""
        release_block(self)


class MappedBlock(Protocol):
    """A shared-memory block with its byte view and its 64-bit view."""

    shm: shared_memory.SharedMemory
    owner: bool
    u64: memoryview


def mapped_views(shm: shared_memory.SharedMemory) -> tuple[memoryview, memoryview]:
    """The block's byte view and its 64-bit view (the rings' counters)."""
    buf = shm.buf
    if buf is None:
        raise RuntimeError(f"shared block {shm.name!r} is already closed")
    return buf, buf.cast("Q")


def release_block(block: MappedBlock) -> None:
    """Release every view into a shared-memory block (its rings share the block's
    views), close it, and remove it if this side created it (`block.owner`)."""
    block.u64.release()
    block.shm.close()  # releases the byte view
    if block.owner:
        with contextlib.suppress(FileNotFoundError):
            block.shm.unlink()
