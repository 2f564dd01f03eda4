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

Who may command: a query whose attachment carries the daemon's token
(`pamd.net.credential`), to this rig by name: a pattern (`pamd/*/cmd/...`) is refused.
An `estop` acts from anyone, credential and pattern or not, and is recorded with who
sent it; an `estop` or `stop` acts whatever its size or extra fields, the rest cut and
recorded (`pamd.net.urgent`); beyond its sender's rate it joins the same verb's
command that waits for its verdict, if any, and gets that verdict. Refusals are
recorded one per kind per second, the next with the count of those between (a flood
cannot grow the recording).
"""

from __future__ import annotations

import contextlib
import json
import sys
import threading
import time
from collections import deque
from collections.abc import Callable
from typing import Any, Protocol

from pamd.commands import REGISTRY, parse_command
from pamd.commands.schema import (
    MAX_WHO_CHARS,
    cap_payload,
    cap_text,
)
from pamd.errors import CommandRefused
from pamd.net import zconf
from pamd.net.answer import StatusAnswer
from pamd.net.board import Board
from pamd.net.credential import matches
from pamd.net.keys import Keys
from pamd.net.memory import trim_heap
from pamd.net.ranges import PressureRanges
from pamd.net.ratelimit import RateLimiter
from pamd.net.refusals import RefusalLog
from pamd.net.seams import CommandPort, LoopStart, Query, RunClock, Verdict
from pamd.net.spec import NetSpec
from pamd.net.stats import TickStats
from pamd.net.status import jsonsafe
from pamd.net.telemetry import StateBatcher
from pamd.net.urgent import salvage

CLOSE_TIMEOUT_S = 3.0
SWITCH_INTERVAL_S = 0.0005  # the io process's: a query callback waits at most this
PUT_BURST = 2.0  # state puts a late pass may catch up with (keeps the phase)
ESTOP = "estop"
TRIM_PERIOD_S = 2.0  # the heap's free memory goes back to the system this often
MAX_PAYLOAD_BYTES = 64 * 1024  # a command's JSON; larger ones are refused unread

RecordFn = Callable[[float, str, dict[str, Any]], None]


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
        self.record = record  # (loop time, kind, data) -> the recording, if any
        self.keys = Keys(spec.rig_id)
        self.batcher = StateBatcher(spec.rig_id, spec.muscles, spec.every_ticks)
        self.stats = TickStats()
        self.answer = StatusAnswer(spec, io_spec, self.stats)
        self.limiter = RateLimiter(spec.command_rate_per_s, spec.command_burst)
        self.ranges = PressureRanges(spec.muscles, lambda: self.board)
        self.session: Any = None
        self.board: Board | None = None
        self.token: Any = None
        self.lock = port.lock  # one lock for the mailbox, the board and the queries
        self.waiting: dict[int, tuple[Query, float, str, int | None]] = {}
        self.to_record: deque[tuple[float, str, dict[str, Any]]] = deque()
        self.to_main: deque[bytes] = deque()  # notices for the daemon's main thread
        self.closing = False
        self.next_id = 1
        self.put_tokens = PUT_BURST
        self.put_t = 0.0
        self.stop_reason: str | None = None
        self.last_t_s = 0.0
        self.rows_mono = time.monotonic()  # when tick records last came in
        self.t0_wall: float | None = None
        self.trim_t = time.monotonic()
        self.refusals = RefusalLog(self._record_io, spec.rig_id)  # recorded per kind
        self.notes: dict[int, str] = {}  # what was cut of an estop or stop, by query
        self.joined: dict[int, list[Query]] = {}  # estops or stops answered with another's
        self.counts = {"state_puts": 0, "events": 0, "commands": 0, "refused_here": 0,
                       "rate_limited": 0, "no_credential": 0, "joined": 0,
                       "status_queries": 0}

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
        self.cmd_q = s.declare_queryable(k.cmd_all, self.on_command, complete=True)
        self.token = s.liveliness().declare_token(k.alive)
        self.zid = str(s.zid())
        self._publish_event("run_start", {"rig_id": self.spec.rig_id, "zid": self.zid,
                                          "muscles": list(self.spec.muscles)})
        return None

    def close(self, reason: str) -> None:
        """Withdraw the token, answer every pending and queued query, close the
        session (bounded: a session that will not close is left to the process's
        exit)."""
        if self.session is None:
            return
        with self.lock:
            self.closing = True  # from now on, commands are refused at once
            self.stop_reason = self.stop_reason or reason
            self._withdraw()
            for k in list(self.waiting):
                self._resolve(k, {"ok": False, "error": f"the daemon stopped ({reason}) "
                                  "before the loop gave its verdict; the command was not "
                                  "applied"})
            self.refusals.flush_due(final=True)  # none goes uncounted
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

    def event(self, t: float, kind: str, data: dict[str, Any]) -> None:
        if kind == "reply":
            return
        if kind == "summary":
            kind = "run_stop"
        t0 = self._t_start()
        self._publish_event(kind, data, None if t0 is None else t - t0)

    def _publish_event(self, kind: str, data: dict[str, Any], t_s: float | None = None) -> None:
        w0 = self._wall0()
        msg = {"t_s": t_s, "wall_s": (w0 + t_s) if (w0 is not None and t_s is not None)
               else time.time(), "kind": kind, "data": jsonsafe(data)}
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
            if self.stop_reason is None and self.board is not None:
                reason = self.board.stopping()
                if reason is not None:
                    self.stop_reason = reason
                    self._withdraw()
            while self.to_main and self.board is not None and self.board.requests.put_blob(
                    self.to_main[0]):
                self.to_main.popleft()
                work += 1
            while self.board is not None and (blob := self.board.replies.get_blob()):
                rep = json.loads(blob)
                self._resolve(int(rep["id"]), rep["verdict"])
                work += 1
            if self.waiting:
                for k, (_q, deadline, verb, _cid) in list(self.waiting.items()):
                    if now > deadline:
                        self._resolve(k, {"ok": False, "error": (
                            f"no verdict from the loop within "
                            f"{self.spec.command_timeout_s:g} s; the {verb} command may "
                            "still be applied (see status)")})
        if self.refusals.pending:
            with self.lock:  # the rest of a flood of refusals, counted
                self.refusals.flush_due()
        if self.to_record:
            self.flush_records()
        if now - self.trim_t >= TRIM_PERIOD_S:
            self.trim_t = now
            trim_heap()
        self.stats.refresh(now)
        return work

    def notify_main(self, msg: dict[str, Any]) -> None:
        """A notice for the daemon's main thread (the recorder's: pamd.record.control), sent
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
                self._send(q, self.keys.status, json.dumps(
                    {"ok": False, "error": f"status failed: {exc!r}"}).encode())

    def _status(self, q: Query) -> None:
        self.counts["status_queries"] += 1
        board = self.board
        body = self.answer.serve(board.read_status if board is not None else lambda: None,
                                 time.monotonic(), self.rows_mono, self.stop_reason, self.counts)
        self._send(q, self.keys.status, body)

    def _send(self, q: Query, key: str, body: bytes) -> None:
        try:
            q.reply(key, body, encoding="application/json")
        except Exception:
            pass  # the querier is gone or the key is not one it accepts
        finally:
            q.drop()

    # -- commands ---------------------------------------------------------------------------
    def _refuse(self, q: Query, key: str, verb: str, args: bytes, sender: str, user: str,
                error: str, record: bool = True, kind: str | None = None) -> None:
        """Answer a refusal; record it (one per kind per RECORD_INTERVAL_S, the next
        saying how many like it were refused meanwhile: a flood of refusals cannot
        grow the recording)."""
        self.counts["refused_here"] += 1
        verdict = {"ok": False, "error": error, "rig": self.spec.rig_id}
        if record:
            self.refusals.refused(verb, args, sender, user, verdict, kind)
        self._send(q, key, json.dumps(verdict).encode())

    def _record_io(self, kind: str, data: dict[str, Any]) -> None:
        now = self.loop_now()
        self.to_record.append((now, kind, data))  # recorded by the io loop
        t0 = self._t_start()
        self._publish_event(kind, data, None if t0 is None else now - t0)

    def _credentialed(self, q: Query) -> bool:
        if not self.spec.token_sha256:
            return True  # a spec without a token (built by hand): commands are open
        try:
            att = q.attachment
            presented = att.to_bytes() if att is not None else None
        except Exception:
            presented = None
        return matches(presented, self.spec.token_sha256)

    def on_command(self, q: Query) -> None:
        """Zenoh's callback thread: refused at once, or into the loop's mailbox."""
        with self.lock:
            try:
                self._command(q, time.monotonic())
            except Exception as exc:  # never leave a query unanswered, nor unrecorded
                error = cap_text(f"refused: the command failed in the io process "
                                 f"({exc.__class__.__name__}: {exc}); the daemon goes on", 300)
                try:
                    key = str(q.key_expr)
                    self._refuse(q, key, Keys.last_chunk(key), b"", "zenoh", "", error)
                except Exception:
                    self._send(q, str(q.key_expr), json.dumps(
                        {"ok": False, "error": error}).encode())

    def _command(self, q: Query, now: float) -> None:
        self.counts["commands"] += 1
        key = str(q.key_expr)
        verb = Keys.last_chunk(key)
        try:
            si = q.source_info
            zid = str(si.source_id.zid) if si is not None else ""
        except Exception:
            zid = ""
        sender = f"zenoh:{zid}" if zid else "zenoh"
        user = cap_text(q.parameters.get("user") or "", MAX_WHO_CHARS)
        raw = q.payload.to_bytes() if q.payload is not None else b""
        if "*" in verb or "$" in verb:
            self._refuse(q, key, verb, raw, sender, user,
                         "name one verb: pamd/<rig>/cmd/<verb>", record=False)
            return
        urgent = REGISTRY.is_urgent(verb)  # estop, stop: they reach the loop while it runs
        pattern = Keys.rig_of(key) != self.spec.rig_id  # `pamd/*/cmd/...`, `pamd/**`
        credentialed = self._credentialed(q)
        if verb == ESTOP:  # anyone who reaches the daemon may stop the rig
            if not credentialed:
                sender = cap_text(f"{sender} (no credential)", MAX_WHO_CHARS)
        elif pattern:
            self._refuse(q, key, verb, raw, sender, user, (
                f"name the rig: pamd/{self.spec.rig_id}/cmd/{verb}, not the pattern "
                f"{cap_text(key, 80)!r}; rig ids are names (only an estop acts on a "
                "pattern); not taken"), kind="pattern")
            return
        elif not credentialed:
            self.counts["no_credential"] += 1
            self._refuse(q, key, verb, raw, sender, user, (
                f"{verb} needs the daemon's command credential: the token in "
                f"{self.spec.token_file or 'its token file'} (readable by the daemon's user "
                "and group; pamd cmd and pamd.connect find it there, or give --token-file "
                "/ PAMD_TOKEN_FILE); not taken"), kind="credential")
            return
        if (self.stop_reason is not None and not urgent) or self.closing:
            self._refuse(q, key, verb, raw, sender, user,
                         f"the daemon is stopping ({self.stop_reason}); command not taken")
            return
        allowed = self.limiter.allow(zid or "unidentified", now)
        if urgent and not allowed and self._join(q, verb):
            return  # a flood of estops: one reaches the loop at a time, all are answered
        if not urgent and not allowed:
            self.counts["rate_limited"] += 1
            self._refuse(q, key, verb, raw, sender, user, (
                f"rate limited: more than {self.spec.command_rate_per_s:g} commands/s "
                f"(burst {self.spec.command_burst}) from {sender}; not taken"), kind="rate")
            return
        note = ""
        if urgent:  # honoured whatever came with it; the rest cut and said so
            payload, note = salvage(verb, raw)
            if note:
                self.refusals.cut(verb, raw, sender, user, note)
        elif len(raw) > MAX_PAYLOAD_BYTES:
            self._refuse(q, key, cap_text(verb, 40), raw, sender, user,
                         f"payload of {len(raw)} bytes, above the limit of "
                         f"{MAX_PAYLOAD_BYTES} bytes; not taken", kind="size")
            return
        else:
            text = raw.decode("utf-8", "replace")
            try:
                payload = json.loads(text) if text.strip() else {}
            except (ValueError, RecursionError) as exc:
                why = exc if isinstance(exc, ValueError) else "nested too deep"
                self._refuse(q, key, verb, raw, sender, user, f"malformed JSON: {why}",
                             kind="json")
                return
        try:
            try:
                parse_command(verb, payload, sender=sender, user=user)
            except CommandRefused:
                if not urgent:
                    raise
                payload = {}  # what salvage kept did not parse: the verb alone, with defaults
            payload = cap_payload(payload)  # what goes on: text fields capped
            self.ranges.check(verb, payload)
        except CommandRefused as exc:
            self._refuse(q, key, verb, raw, sender, user, str(exc))
            return
        k = self.next_id
        self.next_id += 1
        deadline = now + self.spec.command_timeout_s
        self.waiting[k] = (q, deadline, verb, None)
        if note:
            self.notes[k] = note
        if verb in REGISTRY.main_thread:
            assert self.board is not None
            blob = json.dumps({"id": k, "verb": verb, "payload": payload, "sender": sender,
                               "user": user}).encode()
            try:
                taken = self.board.requests.put_blob(blob)
            except ValueError:  # larger than a slot, even with its text capped
                self._resolve(k, {"ok": False, "error": f"{verb}: the request is too large "
                                  f"({len(blob)} bytes); not taken"})
                return
            if not taken:
                self._resolve(k, {"ok": False, "error": "the daemon is busy (request queue "
                                  "full); try again"})
            return
        def on_verdict(verdict: Verdict, _k: int = k) -> None:
            self._resolve(_k, verdict)

        cid = self.port.send(verb, payload, sender, user, on_verdict=on_verdict)
        if cid is not None and k in self.waiting:
            self.waiting[k] = (q, deadline, verb, cid)

    def _join(self, q: Query, verb: str) -> bool:
        """An estop or stop beyond its sender's rate joins the same verb's command that
        waits for the loop's verdict, if any (answered with it): so a flood of them
        neither fills the loop's mailbox nor the recording; the one in flight acts."""
        for k, (_q, _deadline, v, _cid) in self.waiting.items():
            if v == verb:
                self.joined.setdefault(k, []).append(q)
                self.counts["joined"] += 1
                return True
        return False

    def _resolve(self, k: int, verdict: Verdict) -> None:
        entry = self.waiting.pop(k, None)
        if entry is None:
            return  # answered already (timed out)
        q, _deadline, verb, cid = entry
        if cid is not None:
            self.port.waiting.pop(cid, None)
        out = {key: v for key, v in verdict.items() if key != "id"}
        out["rig"] = self.spec.rig_id  # every verdict names the rig that gave it
        note = self.notes.pop(k, None)
        if note:
            out["cut"] = note
        body = json.dumps(jsonsafe(out), default=str).encode()
        self._send(q, self.keys.cmd(verb), body)
        for other in self.joined.pop(k, ()):  # estops or stops that joined this one
            self._send(other, self.keys.cmd(verb), json.dumps(jsonsafe(
                {**out, "joined": True}), default=str).encode())
