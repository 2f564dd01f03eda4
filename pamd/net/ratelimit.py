"""Token buckets for commands: one per sender (its Zenoh id, as its queries declare
it; queries that declare none share one bucket) and one for all senders together, so
a flood is refused in the io process and never reaches the loop's mailbox."""

from __future__ import annotations

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
