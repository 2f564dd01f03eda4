"""What the io process records of the commands it refuses, or takes in part: one record
per kind per interval (`RECORD_INTERVAL_S`), the next of the kind saying how many like
it came between (`refused_unrecorded`), and the rest of a flood said in a `refusals`
record once its interval has passed. So a flood of refusals (too large, not JSON, no
credential, a pattern, over the rate) cannot grow the recording, and none goes
uncounted."""

from __future__ import annotations

import time
from collections.abc import Callable
from typing import Any

from pamd.commands.schema import args_for_record, cap_text
from pamd.net.ratelimit import LineLimiter, kind_of

RECORD_INTERVAL_S = 1.0  # a refusal of each kind recorded at most once per this

RecordIo = Callable[[str, dict[str, Any]], None]


class RefusalLog:
    def __init__(self, record: RecordIo, rig_id: str) -> None:
        """`record(kind, data)`: into the recording and onto the events key."""
        self.record = record
        self.rig_id = rig_id
        self.limiter = LineLimiter(RECORD_INTERVAL_S)

    def refused(self, verb: str, raw: bytes, sender: str, user: str,
                verdict: dict[str, Any], kind: str | None = None) -> None:
        dropped = self.limiter.admit(kind or kind_of(f"{verb[:40]}:{verdict['error']}", 80),
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
        data: dict[str, Any] = {"verb": verb, "args": args_for_record(raw),
                                "sender": sender, "user": user, "note": note}
        if dropped:
            data["cut_unrecorded"] = dropped
        self.record("command_cut", data)

    @property
    def pending(self) -> bool:
        return bool(self.limiter.dropped)

    def flush_due(self, final: bool = False) -> None:
        """The rest of a flood, counted, once its kind's interval has passed (`final`:
        all of it, as the daemon stops)."""
        for kind, n in self.limiter.due(float("inf") if final else time.monotonic()):
            self.record("refusals", {"kind": kind, "refused_unrecorded": n,
                                     "rig": self.rig_id})
