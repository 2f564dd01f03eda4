"""The io process's Zenoh node: one session, in the io process (never in the loop's).

Queries (`status`, `cmd/*`) are answered from Zenoh's callback thread, at once: the
status from the board's snapshot, a command by checking it and putting it into the
loop's mailbox. The callbacks take the interpreter lock of the io process only, and
share one lock (`CommandPort.lock`) with the io loop, which publishes the state it
drains, routes verdicts back to their queries and writes what must be recorded (the
recorder is the io loop's alone). Everything published uses the drop congestion
policy: a frozen subscriber never stalls the io process (nor, through the rings, the
loop).

Commands: `pamd/<rig>/cmd/<verb>` (one wildcard queryable `cmd/*`), JSON object in,
JSON out. Refused here at once: malformed JSON, unknown verbs, missing, extra or
mistyped fields, non-finite numbers (`parse_command`), muscles the rig lacks and
pressures outside the limits, senders over their rate, anything while stopping.
What passes goes through the loop's mailbox (or, for the verbs declared `main_thread`,
`collect` and `model`, through the board to the daemon's main thread); the reply is
the loop's verdict, with the `rig` that gave it. The sender is the Zenoh id the query
declares (`source_info`), the user the `user` selector parameter
(`pamd/sim/cmd/hold?user=ana`): both declared, not authenticated.

What a command must pass, and how it reaches the loop, is the node's command intake
(`pamd.iohost.intake.CommandIntake`).
"""

from __future__ import annotations

import contextlib
import ctypes
import ctypes.util
import json
import os
import sys
import threading
import time
from collections import deque
from collections.abc import Callable
from typing import TYPE_CHECKING, Protocol

from pamd.iohost.answer import StatusAnswer, TickStats
from pamd.iohost.intake import CommandIntake, send_reply
from pamd.wire import zconf
from pamd.wire.board import Board
from pamd.wire.declare.jsonsafe import JsonObject, jsonsafe
from pamd.wire.keys import Keys
from pamd.wire.local_channel import LocalServer
from pamd.wire.net_spec import NetSpec
from pamd.wire.telemetry import StateBatcher

if TYPE_CHECKING:  # types only: the io process loads neither the ports nor (until `open`) zenoh
    import zenoh

    from pamd.wire.seams import CommandPort, LoopStart, Query, RunClock

CLOSE_TIMEOUT_S = 3.0
SWITCH_INTERVAL_S = 0.0005  # the io process's: a query callback waits at most this
PUT_BURST = 2.0  # state puts a late pass may catch up with (keeps the phase)
TRIM_PERIOD_S = 2.0  # the heap's free memory goes back to the system this often

RecordFn = Callable[[float, str, JsonObject], None]


class _Declared(Protocol):
    """A publisher or queryable of the session."""

    def undeclare(self) -> None: ...


class NetNode:
    def __init__(self, spec: NetSpec, io_spec: RunClock, block: LoopStart, port: CommandPort,
                 record: RecordFn) -> None:
        self.spec = spec
        self.io_spec = io_spec
        self.block = block
        self.port = port
        self.record = record  # (loop time, name, data) -> the recording, if any
        self.keys = Keys(spec.rig_id)
        self.batcher = StateBatcher(spec.rig_id, spec.muscles, spec.every_ticks)
        self.stats = TickStats()
        self.answer = StatusAnswer(spec, io_spec, self.stats, block)
        self.session: zenoh.Session | None = None
        self.board: Board | None = None
        self.token: zenoh.LivelinessToken | None = None
        self.lock = port.lock  # one lock for the mailbox, the board and the queries
        self.to_record: deque[tuple[float, str, JsonObject]] = deque()
        self.to_main: deque[bytes] = deque()  # notices for the daemon's main thread
        self.put_tokens = PUT_BURST
        self.put_t = 0.0
        self.last_t_s = 0.0
        self.rows_mono = time.monotonic()  # when tick records last came in
        self.t0_wall: float | None = None
        self.trim_t = time.monotonic()
        self.counts = {"state_puts": 0, "events": 0, "commands": 0, "refused_here": 0,
                       "rate_limited": 0, "no_credential": 0, "joined": 0,
                       "status_queries": 0}
        self.intake = CommandIntake(spec, port, lambda: self.board, self._record_io,
                                    self.counts)
        self.local: LocalServer | None = None  # the local channel (pamd.wire.local_channel)

    # -- life cycle ---------------------------------------------------------------------
    def open(self) -> str | None:
        """Open the session and declare everything; an error text if it cannot."""
        import zenoh


        cfg = zenoh.Config.from_json5(self.spec.zenoh_json)
        try:
            self.session = s = zenoh.open(cfg)
        except Exception as exc:  # zenoh.ZError: endpoint taken, TLS files, ...
            return zconf.open_error(exc, cfg)
        self.board = Board(self.spec.board_name)
        drop, k = zenoh.CongestionControl.DROP, self.keys
        enc = zenoh.Encoding.APPLICATION_JSON
        self.pubs = [s.declare_publisher(k.state(m), encoding=enc, congestion_control=drop)
                     for m in self.spec.muscles]
        self.events_pub = s.declare_publisher(k.events, encoding=enc, congestion_control=drop,
                                              priority=zenoh.Priority.DATA_HIGH)
        sys.setswitchinterval(SWITCH_INTERVAL_S)
        self.status_q = s.declare_queryable(k.status, self._on_status, complete=True)
        self.cmd_q = s.declare_queryable(k.cmd_all, self.intake.on_command, complete=True)
        self.token = s.liveliness().declare_token(k.alive)
        self.zid = str(s.zid())
        self._open_local()
        self._publish_event("run_start", {"rig_id": self.spec.rig_id, "zid": self.zid,
                                          "muscles": list(self.spec.muscles)})
        return None

    def _open_local(self) -> None:
        """The local channel beside the token (pamd.wire.local_channel); where it cannot listen,
        the status says why."""
        if not self.spec.local_socket:
            return
        local = LocalServer(
            self.spec.local_socket,
            {"rig": self.spec.rig_id, "pid": os.getppid(), "listen": list(self.spec.listen)},
            self._on_status, self._on_local_command, self.keys.cmd, self.keys.status)
        note = local.open()
        if note is None:
            self.local = local
            self.answer.local = self.spec.local_socket
        else:
            self.answer.notes.append(note)

    def _on_local_command(self, q: Query, sender: str) -> None:
        """The local channel's thread: the kernel named the sender (its user and pid),
        and only the token's readers reach the socket: no signature needed."""
        self.intake.on_command(q, sender=sender, trusted=True)

    def close(self, reason: str) -> None:
        """Withdraw the token, answer every pending and queued query, close the
        session (bounded: a session that will not close is left to the process's
        exit)."""
        if self.session is None:
            return
        with self.lock:
            self._withdraw()
            self.intake.close(reason)  # from now on, commands are refused at once
        if self.local is not None:
            self.local.close()
            self.local = None
        self.flush_records()
        s = self.session
        self.session = None

        def _close() -> None:
            declared: list[_Declared] = [self.status_q, self.cmd_q, self.events_pub,
                                         *self.pubs]
            for e in declared:
                with contextlib.suppress(Exception):
                    e.undeclare()
            s.close()

        t = threading.Thread(target=_close, name="pamd-zenoh-close", daemon=True)
        t.start()
        t.join(CLOSE_TIMEOUT_S)
        with self.lock:
            if self.board is not None:
                self.board.close()
                self.board = None

    def _withdraw(self) -> None:
        if self.token is not None:
            try:
                self.token.undeclare()
            finally:
                self.token = None

    # -- clocks -------------------------------------------------------------------------
    def _t_start(self) -> float | None:
        return self.block.t_start()

    def loop_now(self) -> float:
        """The loop's clock now (monotonic is one clock for every process here)."""
        t0 = self._t_start() or 0.0
        return t0 + self.last_t_s if self.io_spec.virtual else time.monotonic()

    def _wall0(self) -> float | None:
        if self.t0_wall is None:
            t0 = self._t_start()
            if t0 is not None:
                self.t0_wall = self.io_spec.wall0_ns / 1e9 + (t0 - self.io_spec.clock0_s)
        return self.t0_wall

    # -- from the rings -----------------------------------------------------------------
    def ticks(self, rows: list[tuple[float, ...]]) -> None:
        add = self.batcher.add
        for row in rows:
            add(row)
        self.stats.add(rows)
        self.last_t_s = rows[-1][1]
        self.rows_mono = time.monotonic()

    def event(self, t: float, name: str, data: JsonObject) -> None:
        if name == "reply":
            return
        if name == "summary":
            name = "run_stop"
        t0 = self._t_start()
        self._publish_event(name, data, None if t0 is None else t - t0)

    def _publish_event(self, name: str, data: JsonObject, t_s: float | None = None) -> None:
        w0 = self._wall0()
        msg = {"t_s": t_s, "wall_s": (w0 + t_s) if (w0 is not None and t_s is not None)
               else time.time(), "kind": name, "data": jsonsafe(data)}
        try:
            self.events_pub.put(json.dumps(msg, default=str, allow_nan=False))
            self.counts["events"] += 1
        except Exception:
            pass  # a closing session: the recording still has it

    # -- every pass of the io loop ---------------------------------------------------------
    def poll(self, now: float) -> int:
        """Publish due batches, answer queries, route verdicts; the work done."""
        if self.session is None:
            return 0
        work = 0
        b = self.batcher
        if b.pending:  # token bucket: at most publish_hz puts/s, a late one catches up
            rate = 1.0 / self.spec.publish_period_s
            self.put_tokens = min(PUT_BURST, self.put_tokens + (now - self.put_t) * rate)
            self.put_t = now
            if self.put_tokens >= 1.0:
                self.put_tokens -= 1.0
                w0 = self._wall0()
                for pub, mb in zip(self.pubs, b.batches, strict=True):
                    pub.put(mb.take(w0))
                b.pending = 0
                self.counts["state_puts"] += 1
                work += 1
        with self.lock:
            if self.intake.stop_reason is None and self.board is not None:
                reason = self.board.stopping()
                if reason is not None:
                    self.intake.stop_reason = reason
                    self._withdraw()
            while self.to_main and self.board is not None and self.board.requests.put_blob(
                    self.to_main[0]):
                self.to_main.popleft()
                work += 1
            while self.board is not None and (blob := self.board.replies.get_blob()):
                rep = json.loads(blob)
                self.intake.resolve(int(rep["id"]), rep["verdict"])
                work += 1
            if self.intake.waiting:
                self.intake.expire(now)
            self.intake.watch_token(now)
        if self.intake.refusals.pending:
            with self.lock:  # the rest of a flood of refusals, counted
                self.intake.refusals.flush_due()
        if self.to_record:
            self.flush_records()
        if now - self.trim_t >= TRIM_PERIOD_S:
            self.trim_t = now
            trim_heap()
        self.stats.refresh(now)
        return work

    def notify_main(self, msg: JsonObject) -> None:
        """A notice for the daemon's main thread (the recorder's: pamd.wire.record.control), sent
        on the board's request ring by the next poll (the io loop's thread)."""
        self.to_main.append(json.dumps({"notice": msg}, default=str).encode())

    def flush_records(self) -> None:
        """Events of the query callbacks into the recording (the io loop's thread)."""
        while self.to_record:
            self.record(*self.to_record.popleft())

    # -- status ---------------------------------------------------------------------------
    def _on_status(self, q: Query) -> None:
        """Zenoh's callback thread."""
        with self.lock:
            try:
                self._status(q)
            except Exception as exc:  # never leave a query unanswered
                send_reply(q, self.keys.status, json.dumps(
                    {"ok": False, "error": f"status failed: {exc!r}"}).encode())

    def _status(self, q: Query) -> None:
        self.counts["status_queries"] += 1
        board = self.board
        body = self.answer.serve(board.read_status if board is not None else lambda: None,
                                 time.monotonic(), self.rows_mono, self.intake.stop_reason,
                                 self.counts)
        send_reply(q, self.keys.status, body)

    # -- commands -------------------------------------------------------------------------
    def _record_io(self, name: str, data: JsonObject) -> None:
        """What the command intake records (refusals, cut estops): into the recording
        by the io loop, and onto the events key now."""
        now = self.loop_now()
        self.to_record.append((now, name, data))  # recorded by the io loop
        t0 = self._t_start()
        self._publish_event(name, data, None if t0 is None else now - t0)



# -- memory that clients used goes back to the system when they leave --------------------
# Zenoh (Rust, on the system allocator) and the Foxglove server allocate per client
# session (buffers, queues); freed, that memory stays in glibc's arenas, so the io
# process's RSS grew with each wave of clients (+1.5 MB a wave of 50, 4 waves) although
# nothing leaked. `trim_heap` (glibc `malloc_trim(0)`, a few ms at most, the interpreter
# lock released) returns what is free; the io loop calls it every 2 s. Not
# glibc: nothing to do.

_libc: ctypes.CDLL | None = None
_tried = False


def trim_heap() -> bool:
    """Return the heap's free memory to the system; False where that cannot be done."""
    global _libc, _tried
    if not _tried:
        _tried = True
        try:
            lib = ctypes.CDLL(ctypes.util.find_library("c") or "libc.so.6")
            lib.malloc_trim.argtypes = [ctypes.c_size_t]
            lib.malloc_trim.restype = ctypes.c_int
            _libc = lib
        except (OSError, AttributeError):
            _libc = None
    if _libc is None:
        return False
    _libc.malloc_trim(0)
    return True
