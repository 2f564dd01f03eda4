"""A remote command's way in, in the io process: the checks it must pass before the
loop's mailbox (`CommandIntake`), what is kept of an `estop` or `stop` whatever came
with it (`salvage`), the pressure ranges (`PressureRanges`) and what is recorded of
the commands refused (`RefusalLog`).

Who may command: a query whose attachment carries the daemon's token
(`pamd.wire.credential`), to this rig by name: a pattern (`pamd/*/cmd/...`) is refused.
An `estop` acts from anyone, credential and pattern or not, and is recorded with who
sent it; an `estop` or `stop` acts whatever its size or extra fields, the rest cut and
recorded (`salvage`); beyond its sender's rate it joins the same verb's command that
waits for its verdict, if any, and gets that verdict. Refusals are recorded one per
cause per second, the next with the count of those between (a flood cannot grow the
recording).

Salvage. An `estop` or `stop` always acts: whatever its size, JSON or extra fields, the
verb is honoured first and the rest is cut and said so (`salvage`). The docs have
promised it since the first round (docs/how-to/remote.md, "Limits"); a 100,000-character
reason through `pamd.connect` was refused as too large and the rig did not stop.

What is kept: the verb's declared fields of the right type (text cut to
MAX_TEXT_CHARS, saying how much); what is dropped (extra fields, mistyped ones, an
unreadable or oversized payload) is named in the note, which goes into the recorded
reason and the reply.

Ranges. The io process's range check of a command, before the loop's mailbox: muscle names
and pressures against the limits of the latest status snapshot (refreshed once a
second; the loop checks again against the present state).

Refusals. What the io process records of the commands it refuses, or takes in part: one record
per cause per interval (`RECORD_INTERVAL_S`), the next of the cause saying how many like
it came between (`refused_unrecorded`), and the rest of a flood said in a `refusals`
record once its interval has passed. So a flood of refusals (too large, not JSON, no
credential, a pattern, over the rate) cannot grow the recording, and none goes
uncounted.
"""

from __future__ import annotations

import dataclasses
import json
import re
import time
import typing
from collections.abc import Callable

from pamd.iohost.ratelimit import LineLimiter, RateLimiter, pattern_of
from pamd.wire import credential
from pamd.wire.board import Board
from pamd.wire.credential import STALE
from pamd.wire.declare.jsonsafe import JsonObject, JsonValue, jsonsafe
from pamd.wire.errors import CommandRefused
from pamd.wire.keys import Keys
from pamd.wire.net_spec import NetSpec
from pamd.wire.verbs.args import (
    MAX_TEXT_CHARS,
    MAX_WHO_CHARS,
    args_for_record,
    cap_payload,
    cap_text,
)
from pamd.wire.verbs.table import VERBS, parse_command

if typing.TYPE_CHECKING:  # the node's ports: types only, so the io process never loads them
    from pamd.wire.seams import CommandPort, Query, Verdict

ESTOP = "estop"
MAX_PAYLOAD_BYTES = 64 * 1024  # a command's JSON; larger ones are refused unread


PARSE_MAX_BYTES = 1 << 20  # parsed whole up to this; beyond, only the head is read
HEAD_BYTES = 8 * MAX_TEXT_CHARS
NOTE_CHARS = 120
_FIELD = r'"{name}"\s*:\s*"((?:[^"\\]|\\.)*)'


def _declared(verb: str) -> dict[str, object]:
    """The verb's fields and their types."""
    declared = VERBS.public(verb)
    if declared is None:
        return {}
    hints = typing.get_type_hints(declared.args)
    return {f.name: hints[f.name] for f in dataclasses.fields(declared.args)}


def _fits(value: JsonValue, tp: object) -> bool:
    allowed = [a for a in typing.get_args(tp)] or [tp]
    if isinstance(value, bool):
        return bool in allowed
    if isinstance(value, (int, float)):
        return (float in allowed or int in allowed) and value == value and abs(value) < 1e300
    return any(a is not type(None) and isinstance(value, a) for a in allowed
               if isinstance(a, type))


def _from_head(raw: bytes, fields: dict[str, object]) -> JsonObject:
    """Text fields read from the head of a payload too large (or too broken) to parse."""
    head = raw[:HEAD_BYTES].decode("utf-8", "replace")
    out: JsonObject = {}
    for name, tp in fields.items():
        if str in (typing.get_args(tp) or [tp]):
            m = re.search(_FIELD.format(name=re.escape(name)), head)
            if m:
                try:
                    out[name] = json.loads(f'"{m.group(1)}"')
                except ValueError:
                    out[name] = m.group(1)
    return out


def salvage(verb: str, raw: bytes) -> tuple[JsonObject, str]:
    """(payload the verb's parser takes, note of what was cut or dropped: "" if
    nothing)."""
    fields = _declared(verb)
    notes = []
    got: JsonValue = None
    if len(raw) <= PARSE_MAX_BYTES:
        text = raw.decode("utf-8", "replace")
        try:
            got = json.loads(text) if text.strip() else {}
        except (ValueError, RecursionError):
            notes.append(f"payload of {len(raw)} bytes not JSON")
    else:
        notes.append(f"payload of {len(raw)} bytes read in part")
    if got is None:
        got = _from_head(raw, fields)
    elif not isinstance(got, dict):
        notes.append("payload not a JSON object")
        got = {}
    return salvage_object(verb, got, notes, whole=len(raw) <= PARSE_MAX_BYTES)


def salvage_object(verb: str, got: JsonObject, notes: list[str] | None = None,
                   whole: bool = True) -> tuple[JsonObject, str]:
    """`salvage` of a payload already read (`got`): what the verb takes, and the note
    (`notes` so far; `whole`: its text fields were read whole, so their lengths are
    known)."""
    fields = _declared(verb)
    notes = list(notes or [])
    out: JsonObject = {}
    dropped = []
    for k, v in got.items():
        tp = fields.get(k)
        if tp is None or not _fits(v, tp):
            dropped.append(cap_text(str(k), 40))
            continue
        if isinstance(v, str) and len(v) > MAX_TEXT_CHARS and whole:
            notes.append(f"{k} cut from {len(v)} characters")
        out[k] = v
    if dropped:
        shown = ", ".join(dropped[:8]) + (f" and {len(dropped) - 8} more" if len(dropped) > 8
                                          else "")
        notes.append(f"fields dropped: {shown}")
    note = cap_text("; ".join(notes), NOTE_CHARS)
    if note and "reason" in fields:
        reason = out.get("reason")
        base = reason if isinstance(reason, str) else DEFAULT_REASON.get(verb, verb)
        tail = f" [pamd: {note}]"
        room = max(MAX_TEXT_CHARS - len(tail) - 3, 40)
        out["reason"] = (base if len(base) <= room else base[:room] + "...") + tail
    return out, note


DEFAULT_REASON = {"estop": "emergency stop"}


LIMITS_REFRESH_S = 1.0


class PressureRanges:
    def __init__(self, muscles: tuple[str, ...], board: Callable[[], Board | None]) -> None:
        self.muscles = muscles
        self.board = board
        self._limits: dict[str, float] = {}
        self._limits_t = -1e9

    def check(self, verb: str, p: JsonObject) -> None:
        """Muscle names and pressures against the limits, before the mailbox (the loop
        checks again against the present state)."""
        muscle = p.get("muscle")
        if isinstance(muscle, str) and muscle not in self.muscles:
            raise CommandRefused(f"no muscle named {muscle!r}; muscles: "
                                 f"{', '.join(self.muscles)}")
        fields = VERBS.pressure_fields.get(verb)
        if not fields:
            return
        limits = self._pressure_limits()
        for name in [muscle] if isinstance(muscle, str) else list(self.muscles):
            top = limits.get(name)
            for f in fields:
                v = p.get(f)
                if isinstance(v, (int, float)) and not isinstance(v, bool) and (
                        v < 0.0 or (top is not None and v > top)):
                    rng = f"0-{top:g} bar" if top is not None else "at least 0 bar"
                    raise CommandRefused(f"{name}: {f}={v:g} is outside {rng}")

    def _pressure_limits(self) -> dict[str, float]:
        now = time.monotonic()
        if now - self._limits_t >= LIMITS_REFRESH_S and (board := self.board()) is not None:
            got = board.read_status()
            if got is not None:
                self._limits_t = now
                try:
                    ms = json.loads(got[0]).get("muscles", {})
                    self._limits = {n: float(m["limits"]["max_pressure_bar"])
                                    for n, m in ms.items()}
                except (ValueError, KeyError, TypeError, AttributeError):
                    pass
        return self._limits


RECORD_INTERVAL_S = 1.0  # a refusal of each cause recorded at most once per this

RecordIo = Callable[[str, JsonObject], None]


class RefusalLog:
    def __init__(self, record: RecordIo, rig_id: str) -> None:
        """`record(name, data)`: an event into the recording and onto the events key."""
        self.record = record
        self.rig_id = rig_id
        self.limiter = LineLimiter(RECORD_INTERVAL_S)

    def refused(self, verb: str, raw: bytes, sender: str, user: str,
                verdict: JsonObject, cause: str | None = None) -> None:
        dropped = self.limiter.admit(cause or pattern_of(f"{verb[:40]}:{verdict['error']}", 80),
                                     time.monotonic())
        if dropped is None:
            return
        data = {"verb": cap_text(verb, 40), "args": args_for_record(raw), "sender": sender,
                "user": user, "by": "io", **verdict}
        if dropped:
            data["refused_unrecorded"] = dropped  # like it since the last recorded
        self.record("command", data)

    def cut(self, verb: str, raw: bytes, sender: str, user: str, note: str) -> None:
        """An estop or stop honoured with part of its payload cut."""
        dropped = self.limiter.admit(f"cut:{verb}", time.monotonic())
        if dropped is None:
            return
        data: JsonObject = {"verb": verb, "args": args_for_record(raw),
                                "sender": sender, "user": user, "note": note}
        if dropped:
            data["cut_unrecorded"] = dropped
        self.record("command_cut", data)

    @property
    def pending(self) -> bool:
        return bool(self.limiter.dropped)

    def flush_due(self, final: bool = False) -> None:
        """The rest of a flood, counted, once its cause's interval has passed (`final`:
        all of it, as the daemon stops)."""
        for cause, n in self.limiter.due(float("inf") if final else time.monotonic()):
            self.record("refusals", {"kind": cause, "refused_unrecorded": n,
                                     "rig": self.rig_id})


def send_reply(q: Query, key: str, body: bytes) -> None:
    """Answer a query once and release it (a querier gone is no error)."""
    try:
        q.reply(key, body, encoding="application/json")
    except Exception:
        pass  # the querier is gone or the key is not one it accepts
    finally:
        q.drop()


@dataclasses.dataclass
class _Incoming:
    """A command as it came: its query, key, verb and payload bytes, who sent it (the
    sender's Zenoh id, or "", and its name for the record) and whether its verb is
    urgent (estop, stop)."""

    q: Query
    key: str
    verb: str
    raw: bytes
    zid: str
    sender: str
    user: str
    urgent: bool

    @classmethod
    def of(cls, q: Query, local: str | None) -> _Incoming:
        """The command `q` brings; `local`: its sender as the local channel names it,
        None for a query over Zenoh."""
        key = str(q.key_expr)
        verb = Keys.last_chunk(key)
        zid, sender = cls._zenoh_sender(q) if local is None else ("", local)
        user = cap_text(q.parameters.get("user") or "", MAX_WHO_CHARS)
        raw = q.payload.to_bytes() if q.payload is not None else b""
        return cls(q, key, verb, raw, zid, sender, user,
                   urgent=VERBS.is_urgent(verb))  # estop, stop: reach the running loop

    @staticmethod
    def _zenoh_sender(q: Query) -> tuple[str, str]:
        """(the sender's Zenoh id or "", its name for the record)."""
        try:
            si = q.source_info
            zid = str(si.source_id.zid) if si is not None else ""
        except Exception:
            zid = ""
        return zid, f"zenoh:{zid}" if zid else "zenoh"


class CommandIntake:
    """The node's command path: a query on `cmd/<verb>` refused at once, or into the
    loop's mailbox (or, for the verbs declared `main_thread`, onto the board for the
    daemon's main thread), its reply the loop's verdict. Zenoh's callback thread calls
    `on_command`; the io loop `expire`s the waiting ones and `resolve`s the main
    thread's replies. `counts` is the node's (the status answer says them)."""

    def __init__(self, spec: NetSpec, port: CommandPort, board: Callable[[], Board | None],
                 record_io: RecordIo, counts: dict[str, int]) -> None:
        self.spec = spec
        self.port = port
        self.board = board
        self.lock = port.lock  # one lock for the mailbox, the board and the queries
        self.counts = counts
        self.limiter = RateLimiter(spec.command_rate_per_s, spec.command_burst)
        self.keys = Keys(spec.rig_id)
        self.verifier = (credential.Verifier(spec.token_sha256, spec.run_nonce)
                         if spec.token_sha256 else None)
        self.token_watch = credential.TokenWatch(spec.token_file)
        self.ranges = PressureRanges(spec.muscles, board)
        self.refusals = RefusalLog(record_io, spec.rig_id)  # recorded per cause
        self.waiting: dict[int, tuple[Query, float, str, int | None]] = {}
        self.notes: dict[int, str] = {}  # what was cut of an estop or stop, by query
        self.joined: dict[int, list[Query]] = {}  # estops or stops answered with another's
        self.next_id = 1
        self.stop_reason: str | None = None  # the daemon stops: only urgent verbs pass
        self.closing = False  # the session closes: nothing passes

    def close(self, reason: str) -> None:
        """Refuse from now on; answer every command still waiting (under `lock`)."""
        self.closing = True
        self.stop_reason = self.stop_reason or reason
        for k in list(self.waiting):
            self.resolve(k, {"ok": False, "error": f"the daemon stopped ({reason}) before "
                             "the loop gave its verdict; the command was not applied"})
        self.refusals.flush_due(final=True)  # none goes uncounted

    def expire(self, now: float) -> None:
        """Answer the commands whose verdict is overdue (under `lock`)."""
        for k, (_q, deadline, verb, _cid) in list(self.waiting.items()):
            if now > deadline:
                self.resolve(k, {"ok": False, "error": (
                    f"no verdict from the loop within {self.spec.command_timeout_s:g} s; "
                    f"the {verb} command may still be applied (see status)")})

    def _refuse(self, q: Query, key: str, verb: str, args: bytes, sender: str, user: str,
                error: str, record: bool = True, cause: str | None = None,
                credential: str | None = None) -> None:
        """Answer a refusal; record it (one per cause per RECORD_INTERVAL_S, the next
        saying how many like it were refused meanwhile: a flood of refusals cannot
        grow the recording). `credential`: why the signature was not taken, said in
        the reply for the client (signed for another run: with this run's nonce, so it
        signs again; a wrong signature: it reads its token again)."""
        self.counts["refused_here"] += 1
        verdict: JsonObject = {"ok": False, "error": error, "rig": self.spec.rig_id}
        if record:
            self.refusals.refused(verb, args, sender, user, verdict, cause)
        if credential is not None:
            verdict["credential"] = credential
        if credential == STALE:
            verdict["command_nonce"] = self.spec.run_nonce
        send_reply(q, key, json.dumps(verdict).encode())

    def _credential(self, q: Query, verb: str, raw: bytes) -> str | None:
        """None if the query's attachment signs this command (pamd.wire.credential);
        else why not."""
        if self.verifier is None:
            return None  # a spec without a token (built by hand): commands are open
        try:
            att = q.attachment
            presented = att.to_bytes() if att is not None else None
        except Exception:
            presented = None
        return self.verifier.check(presented, self.spec.rig_id, verb, raw)

    def watch_token(self, now: float) -> None:
        """A rotated token file taken (the io loop, under `lock`)."""
        if self.verifier is not None and (sha := self.token_watch.changed(now)) is not None:
            self.verifier.set_key(sha)
            self.counts["token_rotations"] = self.counts.get("token_rotations", 0) + 1

    def on_command(self, q: Query, sender: str | None = None, trusted: bool = False) -> None:
        """Zenoh's callback thread (or the local channel's, `pamd.wire.local_channel`: `sender`
        named by the kernel, `trusted` as the token's readers are): refused at once, or
        into the loop's mailbox."""
        with self.lock:
            try:
                self._command(q, time.monotonic(), sender, trusted)
            except Exception as exc:  # never leave a query unanswered, nor unrecorded
                error = cap_text(f"refused: the command failed in the io process "
                                 f"({exc.__class__.__name__}: {exc}); the daemon goes on", 300)
                try:
                    key = str(q.key_expr)
                    self._refuse(q, key, Keys.last_chunk(key), b"", "zenoh", "", error)
                except Exception:
                    send_reply(q, str(q.key_expr), json.dumps(
                        {"ok": False, "error": error}).encode())

    def _who_refusal(self, key: str, verb: str, why: str | None) -> tuple[str, str] | None:
        """(error, its cause as recorded) if this sender may not send this command here: a key that
        is a pattern (`pamd/*/cmd/...`, `pamd/<rig>/**/setpoint`), or no valid credential
        (`why`, pamd.wire.credential). An estop passes both (anyone may stop the rig)."""
        if verb == ESTOP:
            return None
        if key != self.keys.cmd(verb):
            return (f"name the rig and the verb: pamd/{self.spec.rig_id}/cmd/{verb}, not the "
                    f"pattern {cap_text(key, 80)!r}; rig ids are names (only an estop acts on "
                    "a pattern); not taken"), "pattern"
        if why is None:
            return None
        self.counts["no_credential"] += 1
        where = self.spec.token_file or "its token file"
        if why == credential.CLEAR:
            error = (f"{verb}: the daemon's token was sent in clear (a pamd client older than "
                     "this daemon): commands are signed, the token never travels; update pamd "
                     "where this came from; not taken")
        elif why == credential.STALE:
            error = (f"{verb}: signed for another run of the daemon (it restarted): sign again "
                     "with the command_nonce its status says (pamd's clients do); not taken")
        elif why == credential.REPLAY:
            error = (f"{verb}: this signed command was taken already (a replay, or a client's "
                     "counter gone back); not taken")
        elif why == credential.BAD:
            error = (f"{verb}: its signature does not match the daemon's command credential "
                     f"(a wrong or rotated token? the token is in {where}); not taken")
        else:
            error = (f"{verb} needs the daemon's command credential: the token in {where} "
                     "(readable by the daemon's user and group; pamd cmd and pamd.connect "
                     "find it there, or give --token-file / PAMD_TOKEN_FILE); not taken")
        return error, "credential"

    def _command(self, q: Query, now: float, local: str | None, trusted: bool) -> None:
        """One command: refused (answered and recorded) at the first check it fails, or
        into the loop's mailbox (or onto the board)."""
        self.counts["commands"] += 1
        c = _Incoming.of(q, local)
        if not self._admitted(c, now, trusted):
            return
        taken = self._payload(c)
        if taken is None:
            return
        payload = self._checked(c, taken[0])
        if payload is not None:
            self._enqueue(c, payload, taken[1], now)

    def _refuse_incoming(self, c: _Incoming, error: str, record: bool = True,
                         cause: str | None = None, credential: str | None = None) -> None:
        self._refuse(c.q, c.key, c.verb, c.raw, c.sender, c.user, error, record=record,
                     cause=cause, credential=credential)

    def _admitted(self, c: _Incoming, now: float, trusted: bool) -> bool:
        """Whether this sender may send this command now: one verb named, a valid
        credential (an estop passes without), the daemon not stopping (urgent verbs
        pass), within the sender's rate. A command refused is answered here."""
        if "*" in c.verb or "$" in c.verb:
            self._refuse_incoming(c, "name one verb: pamd/<rig>/cmd/<verb>", record=False)
            return False
        unsigned = None if trusted else self._credential(c.q, c.verb, c.raw)
        refusal = self._who_refusal(c.key, c.verb, unsigned)
        if refusal is not None:
            self._refuse_incoming(c, refusal[0], cause=refusal[1],
                                  credential=unsigned if refusal[1] == "credential" else None)
            return False
        if unsigned is not None:  # an estop: anyone who reaches the daemon may stop the rig
            c.sender = cap_text(f"{c.sender} (no credential)", MAX_WHO_CHARS)
        if (self.stop_reason is not None and not c.urgent) or self.closing:
            self._refuse_incoming(
                c, f"the daemon is stopping ({self.stop_reason}); command not taken")
            return False
        return self._within_rate(c, now)

    def _within_rate(self, c: _Incoming, now: float) -> bool:
        """Whether the sender is within its command rate. Beyond it an urgent verb joins
        the same verb's command in flight, if any; anything else is refused."""
        allowed = self.limiter.allow(c.zid or c.sender, now)
        if c.urgent and not allowed and self._join(c.q, c.verb):
            return False  # a flood of estops: one reaches the loop at a time, all are answered
        if not c.urgent and not allowed:
            self.counts["rate_limited"] += 1
            self._refuse_incoming(c, (
                f"rate limited: more than {self.spec.command_rate_per_s:g} commands/s "
                f"(burst {self.spec.command_burst}) from {c.sender}; not taken"), cause="rate")
            return False
        return True

    def _payload(self, c: _Incoming) -> tuple[JsonValue, str] | None:
        """(the payload, what was cut of it: "" if nothing), or None if refused: an
        urgent verb's salvaged whatever came with it; any other's read as JSON, within
        MAX_PAYLOAD_BYTES."""
        if c.urgent:  # honoured whatever came with it; the rest cut and said so
            payload, note = salvage(c.verb, c.raw)
            if note:
                self.refusals.cut(c.verb, c.raw, c.sender, c.user, note)
            return payload, note
        if len(c.raw) > MAX_PAYLOAD_BYTES:
            self._refuse(c.q, c.key, cap_text(c.verb, 40), c.raw, c.sender, c.user,
                         f"payload of {len(c.raw)} bytes, above the limit of "
                         f"{MAX_PAYLOAD_BYTES} bytes; not taken", cause="size")
            return None
        text = c.raw.decode("utf-8", "replace")
        try:
            return (json.loads(text) if text.strip() else {}), ""
        except (ValueError, RecursionError) as exc:
            why = exc if isinstance(exc, ValueError) else "nested too deep"
            self._refuse_incoming(c, f"malformed JSON: {why}", cause="json")
            return None

    def _checked(self, c: _Incoming, payload: JsonValue) -> JsonObject | None:
        """The payload as it goes on (text fields capped) if the verb's parser and the
        pressure ranges take it, else None (refused). An urgent verb whose salvaged
        payload does not parse goes on alone, with its defaults."""
        try:
            try:
                parse_command(c.verb, payload, sender=c.sender, user=c.user)
            except CommandRefused:
                if not c.urgent:
                    raise
                payload = {}  # what salvage kept did not parse: the verb alone, with defaults
            checked = cap_payload(payload)  # what goes on: text fields capped
            self.ranges.check(c.verb, checked)
        except CommandRefused as exc:
            self._refuse_incoming(c, str(exc))
            return None
        return checked

    def _enqueue(self, c: _Incoming, payload: JsonObject, note: str, now: float) -> None:
        """Wait for the command's verdict: from the loop's mailbox, or, for the verbs
        declared `main_thread`, from the daemon's main thread through the board."""
        k = self.next_id
        self.next_id += 1
        deadline = now + self.spec.command_timeout_s
        self.waiting[k] = (c.q, deadline, c.verb, None)
        if note:
            self.notes[k] = note
        if c.verb in VERBS.main_thread:
            self._to_main_thread(k, c, payload)
            return
        def on_verdict(verdict: Verdict, _k: int = k) -> None:
            self.resolve(_k, verdict)

        cid = self.port.send(c.verb, payload, c.sender, c.user, on_verdict=on_verdict)
        if cid is not None and k in self.waiting:
            self.waiting[k] = (c.q, deadline, c.verb, cid)

    def _to_main_thread(self, k: int, c: _Incoming, payload: JsonObject) -> None:
        """Put waiting command `k` on the board for the daemon's main thread; refused
        (answered now) when too large for a slot or when the board's queue is full."""
        board = self.board()
        assert board is not None
        blob = json.dumps({"id": k, "verb": c.verb, "payload": payload, "sender": c.sender,
                           "user": c.user}).encode()
        try:
            taken = board.requests.put_blob(blob)
        except ValueError:  # larger than a slot, even with its text capped
            self.resolve(k, {"ok": False, "error": f"{c.verb}: the request is too large "
                              f"({len(blob)} bytes); not taken"})
            return
        if not taken:
            self.resolve(k, {"ok": False, "error": "the daemon is busy (request queue "
                              "full); try again"})

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

    def resolve(self, k: int, verdict: Verdict) -> None:
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
        send_reply(q, Keys(self.spec.rig_id).cmd(verb), body)
        for other in self.joined.pop(k, ()):  # estops or stops that joined this one
            send_reply(other, Keys(self.spec.rig_id).cmd(verb), json.dumps(jsonsafe(
                {**out, "joined": True}), default=str).encode())
