"""Streamed setpoints' deadman (one job of the rig controller, `pamd.loop.control.controller`): a
`setpoint` command with `deadman_s` must be refreshed within that time while the ramp
it started still runs, or the rig goes to its safe state.

What must hold for it to fire: the rig RUNNING the very ramp that setpoint started
(the same profile object), and the loop's clock past the last refresh plus its
timeout. Anything else that took over since (a profile, hold, stop, a fault) ends the
deadman quietly. The tick compares one float, the earliest deadline, and nothing else.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping

from pamd.loop.control.muscle import MuscleController
from pamd.profiles import Profile
from pamd.wire.tick import Sink


class Deadman:
    """The armed deadlines: muscle -> (deadline, the ramp it guards, timeout)."""

    def __init__(self, sink: Sink, go_safe: Callable[[str], None]) -> None:
        """`go_safe`: the rig controller's stop (every muscle to its safe pressure)."""
        self.armed: dict[str, tuple[float, Profile | None, float]] = {}
        self.at = math.inf  # the earliest deadline (inf: none armed)
        self._sink = sink
        self._go_safe = go_safe

    def arm(self, now: float, m: MuscleController, timeout_s: float | None) -> None:
        """A setpoint command (loop's thread): re-arm this muscle's deadman for
        `timeout_s` from `now`, or disarm it (None)."""
        if timeout_s is None:
            self.armed.pop(m.name, None)
        else:
            self.armed[m.name] = (now + timeout_s, m.profile, timeout_s)
        self.at = min((d[0] for d in self.armed.values()), default=math.inf)

    def expire(self, now: float, running: bool,
               by_name: Mapping[str, MuscleController]) -> None:
        """A deadline passed (rare path; `running`: the rig is RUNNING). If the rig
        still runs the ramp that setpoint started, go to the safe state; if something
        else took over since, the deadman no longer applies."""
        for name, (deadline, ramp, timeout_s) in list(self.armed.items()):
            if not running or by_name[name].profile is not ramp:
                del self.armed[name]
            elif now > deadline:
                del self.armed[name]
                reason = (f"deadman: no setpoint for {name} within {timeout_s:g} s; ramping "
                          "to the safe state")
                self._sink.event(now, "deadman", {"muscle": name, "timeout_s": timeout_s})
                self._go_safe(reason)
                running = False
        self.at = min((d[0] for d in self.armed.values()), default=math.inf)
