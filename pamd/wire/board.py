"""The status board: shared memory between the daemon's main process and the io
process, beside the loop's block.

- the status snapshot: JSON the main thread writes a few times a second, under a
  sequence lock (odd while writing), so the io process answers `status` queries at
  once without asking the loop;
- the stop flag and reason: set when a stop is requested, so the io process
  withdraws the liveliness token and refuses new commands at once;
- requests (io -> main) and replies (main -> io): commands whose work needs the main
  thread (`collect` reads and checks a plan file, `model` loads a model file) go
  there instead of the loop's mailbox; the verdict comes back by id. The io process
  also sends its recording notices on `requests` (`{"notice": ...}`);
- control (main -> io): recording control for the io process's recorder
  (`pamd.wire.record.control`: a collection's directory and steps, sent before its plan
  reaches the loop). The io loop reads it, never Zenoh's callback threads.

Single writer per field or ring, as in `pamd.wire.ring`; nothing here blocks.
"""

from __future__ import annotations

import struct
import time
from multiprocessing import shared_memory

from pamd.wire.ring import RING_HDR_BYTES, Ring, mapped_views, release_block

MAGIC = 0x44524F4244AD  # "pamd board"
HDR_BYTES = 1024
U_MAGIC, U_SEQ, U_LEN, U_STOP, U_WRITTEN_NS = range(5)
STOP_TEXT_OFF, STOP_TEXT_MAX = 512, 508
STATUS_OFF = HDR_BYTES
STATUS_MAX = 64 * 1024
RING_SLOTS = 16
REQ_SLOT_BYTES = 4096
REP_SLOT_BYTES = 8192
CTL_SLOTS = 4
CTL_SLOT_BYTES = 32 * 1024  # a collection's steps and metadata
REQ_OFF = STATUS_OFF + STATUS_MAX
REP_OFF = REQ_OFF + RING_HDR_BYTES + RING_SLOTS * REQ_SLOT_BYTES
CTL_OFF = REP_OFF + RING_HDR_BYTES + RING_SLOTS * REP_SLOT_BYTES
TOTAL_BYTES = CTL_OFF + RING_HDR_BYTES + CTL_SLOTS * CTL_SLOT_BYTES
_U32 = struct.Struct("<I")


class Board:
    def __init__(self, name: str | None = None, create: bool = False) -> None:
        if create:
            self.shm = shared_memory.SharedMemory(create=True, size=TOTAL_BYTES)
        else:
            self.shm = shared_memory.SharedMemory(name=name)
        self.owner = create
        self.buf, self.u64 = mapped_views(self.shm)
        if create:
            self.buf[:TOTAL_BYTES] = bytes(TOTAL_BYTES)
            self.u64[U_MAGIC] = MAGIC
        elif self.u64[U_MAGIC] != MAGIC:
            raise RuntimeError(f"shared block {name!r} is not a pamd status board")
        self.requests = Ring(self.buf, self.u64, REQ_OFF, RING_SLOTS, REQ_SLOT_BYTES)
        self.replies = Ring(self.buf, self.u64, REP_OFF, RING_SLOTS, REP_SLOT_BYTES)
        self.control = Ring(self.buf, self.u64, CTL_OFF, CTL_SLOTS, CTL_SLOT_BYTES)

    @property
    def name(self) -> str:
        return self.shm.name

    # -- status snapshot (main thread writes, io process reads) ---------------------------
    def write_status(self, blob: bytes) -> bool:
        if len(blob) > STATUS_MAX:
            return False
        u = self.u64
        u[U_SEQ] = u[U_SEQ] + 1  # odd: writing
        self.buf[STATUS_OFF:STATUS_OFF + len(blob)] = blob
        u[U_LEN] = len(blob)
        u[U_WRITTEN_NS] = time.monotonic_ns()
        u[U_SEQ] = u[U_SEQ] + 1  # even: done
        return True

    def read_status(self, tries: int = 100) -> tuple[bytes, float] | None:
        """The latest snapshot and its age in seconds; None if none was written yet."""
        u = self.u64
        for _ in range(tries):
            s1 = u[U_SEQ]
            if s1 == 0:
                return None
            if s1 & 1:
                time.sleep(0.00002)
                continue
            n = u[U_LEN]
            written = u[U_WRITTEN_NS]
            blob = bytes(self.buf[STATUS_OFF:STATUS_OFF + n])
            if u[U_SEQ] == s1:
                return blob, max(0.0, (time.monotonic_ns() - written) / 1e9)
        return None

    # -- stop flag ---------------------------------------------------------------------
    def set_stopping(self, reason: str) -> None:
        data = reason.encode("utf-8", "replace")[:STOP_TEXT_MAX]
        self.buf[STOP_TEXT_OFF + 4:STOP_TEXT_OFF + 4 + len(data)] = data
        _U32.pack_into(self.buf, STOP_TEXT_OFF, len(data))
        self.u64[U_STOP] = 1

    def stopping(self) -> str | None:
        if not self.u64[U_STOP]:
            return None
        (n,) = _U32.unpack_from(self.buf, STOP_TEXT_OFF)
        return bytes(self.buf[STOP_TEXT_OFF + 4:STOP_TEXT_OFF + 4 + n]).decode("utf-8",
                                                                               "replace")

    def close(self) -> None:
        release_block(self)
