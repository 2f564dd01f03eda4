"""Rate limits of what clients can make the io process do.

`RateLimiter`: token buckets for commands, one per sender (its Zenoh id, as its
queries declare it; queries that declare none share one bucket) and one for all
senders together, so a flood is refused in the io process and never reaches the
loop's mailbox.

`LineLimiter` and `RateLimitedHandler`: what the io process writes about what clients
send (a log line, a recorded refusal) is one line per pattern per interval (lines alike
share a pattern: their text with the numbers as `#`, or a refusal's cause), and the
next line of that pattern says how many were dropped meanwhile; the patterns it keeps
are bounded too. So nothing a client sends can grow a log, the recording or the io
process without bound (a Foxglove client sending garbage frames made the server write
a line per frame: 108 MB in 100 s).
"""

from __future__ import annotations

import logging
import re
import sys
import time
from typing import TextIO

MAX_SENDERS = 1024  # buckets kept; the idlest are forgotten beyond this


class Bucket:
    def __init__(self, rate_per_s: float, burst: float, now: float) -> None:
        self.rate = rate_per_s
        self.burst = burst
        self.tokens = burst
        self.t = now

    def take(self, now: float) -> bool:
        tokens = min(self.burst, self.tokens + (now - self.t) * self.rate)
        self.t = now
        if tokens < 1.0:
            self.tokens = tokens
            return False
        self.tokens = tokens - 1.0
        return True


class RateLimiter:
    """`allow(sender, now)`: False when the sender (or everyone together, at
    `global_factor` times the rate) is over the limit."""

    def __init__(self, rate_per_s: float, burst: int, global_factor: float = 4.0) -> None:
        self.rate = rate_per_s
        self.burst = float(burst)
        self.factor = global_factor
        self.senders: dict[str, Bucket] = {}
        self.all: Bucket | None = None
        self.refused = 0

    def allow(self, sender: str, now: float) -> bool:
        if self.all is None:
            self.all = Bucket(self.rate * self.factor, self.burst * self.factor, now)
        b = self.senders.get(sender)
        if b is None:
            if len(self.senders) >= MAX_SENDERS:
                idlest = min(self.senders, key=lambda k: self.senders[k].t)
                del self.senders[idlest]
            b = self.senders[sender] = Bucket(self.rate, self.burst, now)
        ok = b.take(now) and self.all.take(now)
        if not ok:
            self.refused += 1
        return ok


LINE_INTERVAL_S = 10.0  # one line per pattern per this
MAX_PATTERNS = 256  # patterns kept; beyond, every new one shares one
OTHER_PATTERN = "(other patterns)"
_NUMBERS = re.compile(r"\d+")


def pattern_of(text: str, limit: int = 120) -> str:
    """A line's pattern: its text with every number (addresses, ports, ids, sizes) as `#`."""
    return _NUMBERS.sub("#", text[:limit])


class LineLimiter:
    """`admit(pattern, now)`: None when a line of `pattern` is to be dropped (one went out
    less than `interval_s` ago), else how many of that pattern were dropped since the
    last that went out."""

    def __init__(self, interval_s: float = LINE_INTERVAL_S, max_patterns: int = MAX_PATTERNS
                 ) -> None:
        self.interval_s = interval_s
        self.max_patterns = max_patterns
        self.last: dict[str, float] = {}
        self.dropped: dict[str, int] = {}
        self.total_dropped = 0

    def admit(self, pattern: str, now: float) -> int | None:
        if pattern not in self.last and len(self.last) >= self.max_patterns:
            pattern = OTHER_PATTERN
        t = self.last.get(pattern)
        if t is not None and now - t < self.interval_s:
            self.dropped[pattern] = self.dropped.get(pattern, 0) + 1
            self.total_dropped += 1
            return None
        self.last[pattern] = now
        return self.dropped.pop(pattern, 0)

    def due(self, now: float) -> list[tuple[str, int]]:
        """The patterns whose interval has passed with lines dropped: (pattern, how many),
        said now so that the last of a flood is counted too (the interval starts
        again)."""
        out = []
        for pattern, n in list(self.dropped.items()):
            if now - self.last.get(pattern, -1e18) >= self.interval_s:
                out.append((pattern, n))
                del self.dropped[pattern]
                self.last[pattern] = now
        return out


class RateLimitedHandler(logging.Handler):
    """A logging handler writing one line per pattern (logger and message, numbers
    as `#`) per interval to `stream` (stderr), each saying how many like it were
    dropped before it."""

    def __init__(self, prefix: str, interval_s: float = LINE_INTERVAL_S,
                 stream: TextIO | None = None) -> None:
        super().__init__()
        self.prefix = prefix
        self.limiter = LineLimiter(interval_s)
        self.stream = stream

    def emit(self, record: logging.LogRecord) -> None:
        try:
            msg = record.getMessage()
            dropped = self.limiter.admit(f"{record.name}:{pattern_of(msg)}", time.monotonic())
            if dropped is None:
                return
            more = (f" ({dropped} more like it in the last "
                    f"{self.limiter.interval_s:g} s not shown)" if dropped else "")
            self._write(f"{self.prefix}{msg[:300]}{more}")
        except Exception:
            self.handleError(record)

    def flush_due(self, now: float) -> None:
        """Say the counts of patterns whose interval passed with lines dropped."""
        for pattern, n in self.limiter.due(now):
            self._write(f"{self.prefix}{n} more like \"{pattern.split(':', 1)[-1][:80]}\" in "
                        f"the last {self.limiter.interval_s:g} s not shown")

    def _write(self, line: str) -> None:
        stream = self.stream or sys.stderr
        stream.write(line + "\n")
        stream.flush()


def limit_logger(name: str, prefix: str, level: int = logging.WARNING,
                 interval_s: float = LINE_INTERVAL_S) -> RateLimitedHandler:
    """Route logger `name` (and its children) through one rate-limited handler of
    its own (no propagation to the root's handlers); the handler."""
    logger = logging.getLogger(name)
    for h in list(logger.handlers):
        if isinstance(h, RateLimitedHandler):
            return h
    handler = RateLimitedHandler(prefix, interval_s)
    logger.addHandler(handler)
    logger.setLevel(level)
    logger.propagate = False
    return handler
