"""A command's verdict, waited for by the thread that sent it (the daemon's API, the
service keeper's reload) and set by the loop's thread."""

from __future__ import annotations

import threading

from pamd.wire.declare.jsonsafe import JsonObject


class PendingCommand:
    """A command's verdict, set by the loop's thread."""

    def __init__(self) -> None:
        self._done = threading.Event()
        self.verdict: JsonObject = {}

    def set(self, verdict: JsonObject) -> None:
        self.verdict = verdict
        self._done.set()

    @property
    def done(self) -> bool:
        return self._done.is_set()

    def result(self, timeout_s: float) -> JsonObject:
        if not self._done.wait(timeout_s):
            return {"ok": False, "error": f"no verdict from the loop within {timeout_s:g} s"}
        return self.verdict
