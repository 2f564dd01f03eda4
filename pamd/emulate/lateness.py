"""How late the emulated devices were: the stand-in for hardware shares this PC's
CPUs, so unlike a real module with a CPU of its own it can be starved. Each timed
activity of the emulator (the physics step, an encoder's TPDO timer, the Modbus
servers' event loop) notes how late it woke against its own schedule; the
emulator's closing statistics say the worst, so a fault in a test or bench of pamd
can be told apart from a device that was itself late (which a real rig's would not be).
"""

from __future__ import annotations

import threading

#: a wake-up later than this is counted (a real module's timers keep 1 ms)
LATE_S = 0.01


class Lateness:
    """The worst lateness seen and how many wake-ups were later than `LATE_S`."""

    def __init__(self) -> None:
        self.worst_s = 0.0
        self.late = 0
        self._lock = threading.Lock()

    def note(self, late_s: float) -> None:
        """One wake-up `late_s` after it was due (<= 0: on time)."""
        if late_s > self.worst_s or late_s > LATE_S:
            with self._lock:
                self.late += late_s > LATE_S
                self.worst_s = max(self.worst_s, late_s)

    def reset(self) -> None:
        """Forget what was seen (the devices' start-up is their boot, not their service)."""
        with self._lock:
            self.worst_s, self.late = 0.0, 0

    def summary(self) -> dict[str, float]:
        return {"worst_ms": round(1000.0 * self.worst_s, 1), f"later_than_{LATE_S * 1000:g}_ms":
                self.late}
