"""What the service keeper (`pamd.daemon.service.keeper`) and its parts use of the daemon's
rig controller and loop: narrow ports, so that the keeper gets the parts it looks
after and not the daemon (nor the controller's and loop's classes)."""

from __future__ import annotations

import time
from collections import deque
from collections.abc import Sequence
from typing import Protocol

from pamd.config.loader import LoadedConfig
from pamd.drivers.safe_outputs import SafeMuscle
from pamd.loop.rt import RealtimeSession
from pamd.loop.safety.supervisor import Supervisor
from pamd.loop.tick_timing import TickTiming
from pamd.wire.declare.jsonsafe import JsonObject


class KeptRig(Protocol):
    """What the keeper uses of the rig's controller (`pamd.loop.control.controller.RigController`):
    its supervisor (the latched fault, the state), the reload's fate (status shows it;
    the reloader and the loop's `reload` handler write it), the loop's time, the
    muscles' safe pressures (the safe outputs kept), whether it is at rest and why not."""

    reload_note: JsonObject | None

    @property
    def supervisor(self) -> Supervisor: ...
    @property
    def now(self) -> float: ...
    @property
    def muscles(self) -> Sequence[SafeMuscleView]: ...
    def at_rest(self) -> bool: ...
    def rest_text(self) -> str: ...


class SafeMuscleView(SafeMuscle, Protocol):
    """A muscle as the safe outputs file names it: its actuation's safe outputs (each
    output with its name) and safe pressure (`SafeMuscle`), its name and load."""

    @property
    def name(self) -> str: ...
    @property
    def load_kg(self) -> float: ...


class KeptLoop(Protocol):
    """What the keeper uses of the loop (`pamd.loop.loop.Loop`): whether it ticks and when it
    last did (systemd's watchdog, the stall the main thread sees), how it ended, the
    real-time session of its process, and the reload's hand-over and stall limits."""

    running: bool
    virtual: bool
    handed_over: bool
    stopped_reason: str
    last_tick_done: float
    stall_s: float
    timing: TickTiming
    rt: RealtimeSession
    notices: deque[str]

    @property
    def stall_fault_s(self) -> float: ...
    def request_handover(self, reason: str) -> None: ...
    def set_stall_limits(self, cfg: LoadedConfig) -> None: ...


def tick_gap_s(loop: KeptLoop) -> float:
    """Seconds since the loop last completed a tick (NaN before the first)."""
    now = time.monotonic()  # read first: a late main thread never sees a false gap
    return now - loop.last_tick_done
