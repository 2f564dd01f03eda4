"""What every field-device driver shares: its own I/O thread, counters, a short log
of recent errors naming the device and channel, reconnect backoff, and the rule
that turns persistent failure into `fault` (and clears it once the device answers
again; the supervisor's latch is cleared by the operator's `reset`).

The loop never waits on any of this: it reads `in_values` / `in_stamps_s`, which the
thread keeps current (value first, then stamp), and calls `write()`, which only
stores the value for the thread to send.
"""

from __future__ import annotations

import math
import threading
import time
from abc import abstractmethod
from collections import deque
from dataclasses import dataclass, field
from typing import Any

from pamd.drivers import Clock, Driver, DriverHealth

RECENT_ERRORS = 20


@dataclass
class DeviceHealth(DriverHealth):
    """DriverHealth plus the device's description, link state and recent errors."""

    device: str = ""
    connected: bool = False
    errors: list[str] = field(default_factory=list)


class Backoff:
    """Reconnect delays doubling from `min_s` to `max_s`."""

    def __init__(self, min_s: float, max_s: float) -> None:
        self.min_s = min_s
        self.max_s = max(max_s, min_s)
        self.delay_s = min_s

    def next(self) -> float:
        d = self.delay_s
        self.delay_s = min(self.max_s, self.delay_s * 2.0)
        return d

    def reset(self) -> None:
        self.delay_s = self.min_s


class ThreadedDriver(Driver):
    """A driver whose bus I/O runs in `run()` on its own daemon thread.

    Subclasses implement `describe()` (the device, for messages) and `run()` (loop
    until `self.stopping` is set; call `failing(what)` / `healthy()` after each
    cycle). `fault_after_s` is how long failure must last before `fault` is set.
    """

    fault_after_s: float = 0.5

    def __init__(self, name: str, options: Any) -> None:  # Any: as Driver's (its options_type)
        super().__init__(name, options)
        self.counters: dict[str, int] = {}
        self.recent_errors: deque[str] = deque(maxlen=RECENT_ERRORS)
        self.stopping = threading.Event()
        self.connected = False
        self.clock: Clock = time.monotonic
        self._thread: threading.Thread | None = None
        self._failing_since = math.inf
        self._lock = threading.Lock()

    # -- to implement ---------------------------------------------------------------
    @abstractmethod
    def describe(self) -> str:
        """The device in words, e.g. "modbus 'io' (tcp 127.0.0.1:502, id 1)"."""

    @abstractmethod
    def run(self) -> None:
        """The I/O loop; returns when `self.stopping` is set."""

    # -- life cycle -------------------------------------------------------------------
    def open(self, clock: Clock) -> None:
        """Start the I/O thread; never waits for the device."""
        if self._thread is not None:
            return
        self.clock = clock
        self.stopping.clear()
        self._thread = threading.Thread(target=self._main, name=f"pamd-drv-{self.name}",
                                        daemon=True)
        self._thread.start()

    def close(self) -> None:
        self.stopping.set()
        t = self._thread
        if t is not None and t is not threading.current_thread():
            t.join(5.0)
        self._thread = None
        self.release()

    def release(self) -> None:  # noqa: B027 - optional hook
        """Release the device (called from `close` after the thread has ended)."""

    def _main(self) -> None:
        try:
            self.run()
        except Exception as exc:  # the daemon must survive a driver bug: fault instead
            self.count("thread_crashes")
            self.fault = f"{self.describe()}: I/O thread stopped: {exc!r}"
            self.recent_errors.append(self.fault)

    @property
    def alive(self) -> bool:
        return self._thread is not None and self._thread.is_alive()

    # -- bookkeeping --------------------------------------------------------------------
    def count(self, key: str, n: int = 1) -> None:
        with self._lock:
            self.counters[key] = self.counters.get(key, 0) + n

    def error(self, key: str, message: str, channels: tuple[str, ...] = ()) -> str:
        """Count an error (also per channel) and log it with the device named."""
        self.count(key)
        for ch in channels:
            self.count(f"errors.{ch}")
        text = f"{self.describe()}: {message}"
        self.recent_errors.append(text)
        return text

    def failing(self, what: str) -> None:
        """This cycle failed because of `what`; fault if it has lasted fault_after_s."""
        now = time.monotonic()
        if self._failing_since == math.inf:
            self._failing_since = now
        elif now - self._failing_since >= self.fault_after_s and self.fault is None:
            self.fault = f"{self.describe()}: {what}"
            self.count("faults")

    def healthy(self) -> None:
        """A fully good cycle: forget the failure; clear our own fault (the supervisor
        keeps its latch until reset)."""
        self._failing_since = math.inf
        if self.fault is not None:
            self.fault = None
            self.count("recoveries")

    def health(self) -> DeviceHealth:
        with self._lock:
            counters = dict(self.counters)
        return DeviceHealth(ok=self.fault is None and self.connected, fault=self.fault,
                            counters=counters, device=self.describe(),
                            connected=self.connected, errors=list(self.recent_errors))

    def stamp(self, index: int, value: float, now_s: float, jitter_s: float = 0.0) -> None:
        """Publish one input: value and jitter first, then its stamp. `now_s` is the
        device's sample time where the protocol gives one, else the arrival; then
        `jitter_s` says how far from it the value may have been taken."""
        self.in_values[index] = value
        self.in_jitter_s[index] = jitter_s
        self.in_stamps_s[index] = now_s


class ArrivalWindow:
    """When a value read from a stream (CAN frames, serial lines) was taken, as far as
    the reader knows: no earlier than the last time it found the stream idle (a read
    that had to wait, so nothing was queued). A frame read at once after the thread was
    held up may have waited in the socket since then: `jitter_s(now)` says how long.

    `before_read(t)` just before a blocking read, `after_read(t, got)` after it."""

    #: a read that waited this long found the queue empty
    WAITED_S = 0.0002

    def __init__(self) -> None:
        self.idle_at_s = -math.inf
        self._called_s = -math.inf

    def before_read(self, t_s: float) -> None:
        self._called_s = t_s

    def after_read(self, t_s: float, got: bool) -> None:
        if not got:
            self.idle_at_s = t_s  # nothing came: the queue is empty now
        elif t_s - self._called_s >= self.WAITED_S:
            self.idle_at_s = self._called_s  # it waited: it came after the call

    def jitter_s(self, now_s: float) -> float:
        j = now_s - self.idle_at_s
        return j if j < 1e9 else 0.0
