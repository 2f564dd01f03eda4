"""The loop process's side of the io process: start and watch it, hand it one tick
record per tick (`RingSink`), take commands from it (`RingMailbox`).

The tick path (`RingSink.put`) takes no lock, does no I/O and allocates nothing but
the transient slice view: a memoryview slice assignment copies the record's bytes
into the next slot and the head counter is bumped. It also watches the io process:
the io process bumps a heartbeat on every pass; only when the heartbeat has not
moved for `QUIET_TICKS` ticks does the sink poll the process's sentinel (one
`select` with zero timeout), so a dead io process is seen within a tick or two at
the cost of a couple of integer reads per tick.

A full ring in real time drops the record (put returns False, the loop counts it,
and the count goes into the shared header at once, `C_LOOP_LOST`, so the status says
it while the io process is still behind) and records a `lost_records` event once space
is back, or after each second of a loss that goes on (`ongoing`). With the virtual
clock the sink waits for space instead, so a virtual run loses nothing.
"""

from __future__ import annotations

import json
import multiprocessing
import select
import threading
import time
from array import array
from collections import deque
from collections.abc import Callable
from multiprocessing.process import BaseProcess

from pamd.iohost.io_spec import IoSpec
from pamd.iohost.process import io_main
from pamd.loop.control.summary import LocalMailbox
from pamd.wire.declare.jsonsafe import JsonObject
from pamd.wire.errors import CommandRefused, RecordingError
from pamd.wire.ring import (
    C_HEARTBEAT,
    C_IO_STATE,
    C_LOOP_LOST,
    C_LOST_EVENTS,
    C_RECORDED,
    C_STOP,
    IO_DONE,
    IO_FAILED,
    IO_STARTING,
    BlockLayout,
    SharedBlock,
)
from pamd.wire.tick import I_T, I_TICK, Mailbox
from pamd.wire.verbs.args import Command
from pamd.wire.verbs.table import parse_command

QUIET_TICKS = 1
DROP_REPORT_S = 1.0  # a loss that goes on is said this often (loop time), not only at its end
HELD_EVENTS_MAX = 4096  # events (a burst's verdicts) waiting for room in the ring, and
# events of other threads waiting for the loop's thread to send them
START_TIMEOUT_S = 30.0
STOP_TIMEOUT_S = 60.0

FailureHandler = Callable[[str, str], None]  # (what: "death" | "write", reason)


class IoLink:
    """Owns the shared block and the io process."""

    def __init__(self, spec: IoSpec, block: SharedBlock) -> None:
        self.spec = spec
        self.block = block
        self.proc: BaseProcess | None = None
        self.closed = False
        self._status: JsonObject = {}  # the last status, kept once the block is closed
        self._files: list[str] = []

    @classmethod
    def create(cls, make_spec: Callable[[str], IoSpec], layout: BlockLayout) -> IoLink:
        block = SharedBlock(layout, create=True)
        return cls(make_spec(block.name), block)

    def start(self, timeout_s: float = START_TIMEOUT_S) -> None:
        """Spawn the io process and wait until it has opened its file (or failed)."""

        ctx = multiprocessing.get_context("spawn")  # never fork a process with threads
        self.proc = proc = ctx.Process(target=io_main, args=(self.spec,), name="pamd-io",
                                       daemon=True)
        proc.start()
        t0 = time.monotonic()
        while self.block.get(C_IO_STATE) == IO_STARTING:
            if not proc.is_alive():
                self._cleanup()
                raise RecordingError(f"the io process exited at start (code "
                                     f"{proc.exitcode})")
            if time.monotonic() - t0 > timeout_s:
                proc.kill()
                self._cleanup()
                raise RecordingError(f"the io process did not start within {timeout_s:g} s")
            time.sleep(0.005)
        if self.block.get(C_IO_STATE) == IO_FAILED:
            err = self.block.error()
            proc.join(5.0)
            self._cleanup()
            raise RecordingError(err)

    @property
    def pid(self) -> int | None:
        return self.proc.pid if self.proc is not None else None

    @property
    def sentinel(self) -> int:
        if self.proc is None:
            raise RuntimeError("the io process was not started")
        return self.proc.sentinel

    def files(self) -> list[str]:
        return self.block.files() if not self.closed else self._files

    def status(self) -> JsonObject:
        if self.closed:
            return dict(self._status)
        st = self.block.get(C_IO_STATE)
        return {
            "files": self.block.files(),
            "ticks_recorded": self.block.get(C_RECORDED),
            "lost_events": self.block.get(C_LOST_EVENTS),
            "state": {0: "starting", 1: "recording", 2: "failed", 3: "finished"}.get(st, "?"),
            "error": self.block.error() or None,
        }

    def close(self, timeout_s: float = STOP_TIMEOUT_S) -> None:
        """Ask the io process to drain, finalise and exit; wait for it."""
        if self.closed:
            return
        self.block.set(C_STOP, 1)
        if self.proc is not None:
            self.proc.join(timeout_s)
            if self.proc.is_alive():
                self.proc.kill()
                self.proc.join(5.0)
        self._cleanup()

    def _cleanup(self) -> None:
        self._status = self.status() if not self.closed else self._status
        self._files = self._status["files"]
        self.closed = True
        self.block.close()


class RingSink:
    """The sink the loop hands its records to (a `SummarySink` downstream)."""

    def __init__(self, link: IoLink, virtual: bool, t_start: Callable[[], float],
                 on_failure: FailureHandler, notify: Callable[[str], None],
                 keeps_draining: bool = False) -> None:
        """`keeps_draining`: the io process also publishes (telemetry), so after a
        write failure it goes on taking records and events (only its recording
        stopped); without telemetry the sink stops feeding it."""
        self.link = link
        self.keeps_draining = keeps_draining
        self.write_failed = False
        self.block = link.block
        self.ring = link.block.ticks
        self.events_ring = link.block.events
        self.u64 = link.block.u64
        self.virtual = virtual
        self.t_start = t_start
        self.on_failure = on_failure
        self.notify = notify
        self.active = True
        self.failure: str | None = None
        self._rec: array[float] | None = None
        self._mv: memoryview | None = None
        self._hb = -1
        self._quiet = 0
        self._started = False
        self._sentinel = -1  # the process's sentinel fd, once it runs
        self._dropped = 0
        self._drop_first = -1
        self._drop_last = -1
        self._drop_t = 0.0  # loop time of the first record lost since the last report
        self.lost_records = 0
        self.lost_events = 0
        self._producer: int | None = None  # the loop's thread, bound at the first put
        self._pending: deque[tuple[float, str, JsonObject]] = deque()
        self._held: deque[bytes] = deque()  # events waiting for room in the ring

    # -- watch ------------------------------------------------------------------------
    def _dead(self) -> bool:
        if self._sentinel < 0:
            self._sentinel = self.link.sentinel
        return bool(select.select([self._sentinel], [], [], 0)[0])

    def _lose_io(self, what: str, reason: str) -> None:
        self.active = False
        self.failure = reason
        self.on_failure(what, reason)

    def _ensure_start(self) -> None:
        """First put, in the loop's thread: from now on it alone writes the rings."""
        self._producer = threading.get_ident()
        self._started = True
        self.block.set_t_start(self.t_start())

    # -- the tick path ----------------------------------------------------------------
    def put(self, record: array[float]) -> bool:
        if not self.active:
            return True
        u = self.u64
        hb = u[C_HEARTBEAT]
        if hb != self._hb:
            self._hb = hb
            self._quiet = 0
        else:
            self._quiet += 1
            if self._quiet >= QUIET_TICKS and self._dead():
                self._lose_io("death", f"the io process (pid {self.link.pid}) died")
                return True
        if u[C_IO_STATE] == IO_FAILED and not self.write_failed and self._io_failed():
            return True
        mv = self._mv
        if record is not self._rec or mv is None:
            self._rec = record
            self._mv = mv = memoryview(record).cast("B")
        if not self._started:
            self._ensure_start()
        if self._held:
            self._flush_held()
        if self._pending:
            self._flush_pending()
        if not self.ring.put(mv):
            return self._ring_full(record, mv)
        if self._dropped:
            self._report_drops()
        return True

    def _io_failed(self) -> bool:
        """The io process failed to write (rare path): said once. Returns whether the io
        is lost (it no longer takes records); else it stopped recording but still
        publishes, and keeps getting the records, so status and telemetry show what the
        loop does now."""
        self.write_failed = True
        if not self.keeps_draining:
            self._lose_io("write", self.block.error() or "the io process failed")
            return True
        self.failure = self.block.error() or "the io process failed"
        self.on_failure("write", self.failure)
        return False

    def _ring_full(self, record: array[float], mv: memoryview) -> bool:
        """The ring is full (the io process is behind). On the real clock the record is
        lost, counted and said (`put` returns False); on the virtual clock the loop waits
        for room, unless the io process died or failed."""
        u = self.u64
        if not self.virtual:
            if self._dropped == 0:
                self._drop_first = int(record[I_TICK])
                self._drop_t = record[I_T]
            self._dropped += 1
            self._drop_last = int(record[I_TICK])
            self.lost_records += 1
            u[C_LOOP_LOST] = self.lost_records  # the status says it now
            if record[I_T] - self._drop_t >= DROP_REPORT_S:
                self._report_drops(ongoing=True)
            return False
        while not self.ring.put(mv):
            if self._dead():
                self._lose_io("death", f"the io process (pid {self.link.pid}) died")
                return True
            if u[C_IO_STATE] == IO_FAILED and not self.keeps_draining:
                self._lose_io("write", self.block.error() or "the io process failed")
                return True
            time.sleep(0.0002)
        if self._dropped:
            self._report_drops()
        return True

    @property
    def unreported_drops(self) -> int:
        """Tick records lost to a full ring and not yet reported as an event."""
        return self._dropped

    def _report_drops(self, ongoing: bool = False) -> None:
        """Say the records lost since the last report: when the ring has room again, or
        (`ongoing`) after each DROP_REPORT_S of a loss that goes on."""
        n, first, last = self._dropped, self._drop_first, self._drop_last
        self._dropped = 0
        still = "; the io process is still behind" if ongoing else ""
        msg = (f"recording: the io ring was full, {n} tick record(s) lost (ticks {first}-"
               f"{last}; {self.lost_records} so far{still})")
        self.notify(msg)
        data: JsonObject = {"count": n, "first_tick": first, "last_tick": last,
                            "total": self.lost_records}
        if ongoing:
            data["ongoing"] = True
        self.event(self._rec[1] + self.t_start() if self._rec is not None else 0.0,
                   "lost_records", data)

    # -- events -----------------------------------------------------------------------
    def event(self, t_s: float, name: str, data: JsonObject) -> None:
        if not self.active:
            return
        if threading.get_ident() != self._producer:
            if len(self._pending) < HELD_EVENTS_MAX:  # the loop's thread sends it
                self._pending.append((t_s, name, data))
            else:  # the loop's thread takes none (it has stopped): counted, not kept
                self.lost_events += 1
                self.u64[C_LOST_EVENTS] = self.lost_events
            return
        blob = self._encode(t_s, name, data)
        if self._held:  # after the ones waiting, in order
            self._flush_held()
        if not self._held and self.events_ring.put_blob(blob):
            return
        if not self.virtual and name != "summary":
            if len(self._held) < HELD_EVENTS_MAX:  # a burst's verdicts wait, never lost
                self._held.append(blob)
                return
            self.lost_events += 1
            self.u64[C_LOST_EVENTS] = self.lost_events
            return
        self._wait_held()  # the virtual clock (and the summary) wait for room instead
        while not self.events_ring.put_blob(blob):
            if self._dead() or self._io_gone():
                return
            time.sleep(0.0002)

    def _io_gone(self) -> bool:
        """The io process takes no more events (finished, or failed without telemetry)."""
        st = self.u64[C_IO_STATE]
        return st == IO_DONE or (st == IO_FAILED and not self.keeps_draining)

    def _encode(self, t_s: float, name: str, data: JsonObject) -> bytes:
        blob = json.dumps({"t": t_s, "kind": name, "data": data}, default=str).encode()
        cap = self.events_ring.slot_bytes - 4
        if len(blob) > cap:
            text = json.dumps(data, default=str)[: cap // 2]
            blob = json.dumps({"t": t_s, "kind": name,
                               "data": {"truncated": True, "text": text}}).encode()
        return blob

    def _flush_held(self) -> None:
        """Events the ring had no room for, as far as it has now (the loop's thread)."""
        held, ring = self._held, self.events_ring
        while held and ring.put_blob(held[0]):
            held.popleft()

    def _wait_held(self) -> None:
        """Every held event into the ring, waiting for room (not on the tick path)."""
        while self._held:
            self._flush_held()
            if not self._held or self._dead() or self._io_gone():
                return
            time.sleep(0.0002)

    def _flush_pending(self) -> None:
        while self._pending:
            t_s, name, data = self._pending.popleft()
            self.event(t_s, name, data)

    def finish(self, summary: JsonObject) -> None:
        """Last words, from the thread that owns the rings once the loop has ended."""
        self._producer = threading.get_ident()
        if not self._started:
            self._started = True
            self.block.set_t_start(self.t_start())
        if self.active:
            self._flush_pending()
            self._wait_held()
            if self._dropped:
                self._report_drops()
            self.event(0.0, "summary", summary)

    def close(self) -> None:
        pass  # the daemon closes the link after `finish`


class RingMailbox:
    """Commands from the io process, polled by the loop once per tick (never blocks).
    A command is re-checked with `parse_command`; its verdict goes back to the io
    process as a `reply` event carrying the command's id."""

    def __init__(self, link: IoLink, sink: RingSink, now: Callable[[], float]) -> None:
        self.ring = link.block.commands
        self.sink = sink
        self.now = now

    def poll(self) -> Command | None:
        if self.ring.available() <= 0:
            return None
        blob = self.ring.get_blob()
        if blob is None:
            return None
        try:
            msg = json.loads(blob)
            cid = int(msg.get("id", 0))
        except (ValueError, AttributeError, TypeError, RecursionError):
            return None  # not the io process's: it always sends an object with an id

        def reply(verdict: JsonObject, _cid: int = cid) -> None:
            self.sink.event(self.now(), "reply", {"id": _cid, **verdict})

        try:
            return parse_command(str(msg.get("verb")), msg.get("payload"),
                                 sender=str(msg.get("sender", "io")),
                                 user=str(msg.get("user", "")), reply=reply)
        except CommandRefused as exc:
            reply({"ok": False, "error": str(exc)})
        except Exception as exc:  # never the loop's end: a refusal with the reason
            reply({"ok": False, "error": f"{msg.get('verb')!s:.40}: refused: "
                   f"{exc.__class__.__name__} while parsing it"})
        return None


class MultiMailbox:
    """Polls several mailboxes in order (local commands first)."""

    def __init__(self, local: LocalMailbox, *others: Mailbox) -> None:
        self.local = local
        self.boxes: tuple[Mailbox, ...] = (local, *others)

    def put(self, cmd: Command) -> None:
        self.local.put(cmd)

    def poll(self) -> Command | None:
        for b in self.boxes:
            cmd: Command | None = b.poll()  # Any: tick.Mailbox.poll's (it cannot name Command)
            if cmd is not None:
                return cmd
        return None
